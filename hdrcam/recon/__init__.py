"""Reconstruction networks (paper Sec. 4): residual splitting, highlight U-Net, fusion; their losses."""
