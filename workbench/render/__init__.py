"""Render (DESIGN.md §7): synthetic photos of the decorated part on its fixture, with their truth."""
