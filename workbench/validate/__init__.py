"""Validate (DESIGN.md §6): photos of the decorated part, posed, warped into each view and scored."""
