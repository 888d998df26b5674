"""Views (paper §3.1): visibility of the surface from each designed camera, and ownership."""
