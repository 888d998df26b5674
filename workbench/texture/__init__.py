"""Global texture (paper §3.3, per pixel): the print synthesised from the owning views."""
