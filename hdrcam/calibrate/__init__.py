"""PSF calibration from point-source brackets (``hdrcam calibrate psf``)."""
