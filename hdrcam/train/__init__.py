"""Training: end-to-end DOE design, fine-tuning on a measured PSF, checkpoints."""
