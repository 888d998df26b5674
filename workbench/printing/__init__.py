"""Print (DESIGN.md §5): PDFs at true physical scale with marks, and marker boards."""
