"""HDR from RAW brackets: loading and checking brackets, exposure ratios, inverse-variance merging, PSF calibration."""
