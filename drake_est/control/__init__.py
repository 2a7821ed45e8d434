"""Controllers (roadmap: iLQR/DDP trajectory optimization and model-based RL, thesis Ch. 5 and 11).

Not implemented yet; this package is their home."""
