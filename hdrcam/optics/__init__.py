"""Wave optics of the DOE camera (paper Sec. 3): height maps, propagation, PSFs, fabrication."""
