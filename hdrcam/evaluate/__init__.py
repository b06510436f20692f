"""Evaluation: HDR metrics, test-set runs of checkpoints against the LDR capture and baselines."""
