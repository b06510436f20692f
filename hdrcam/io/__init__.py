"""File input and output: RAW, EXR, PNG previews, demosaicing of Bayer data, atomic writes."""
