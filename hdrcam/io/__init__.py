"""File input and output: EXR, PNG previews, atomic writes."""
