"""Seam tracking (roadmap: particle-filter tool-pose estimator in a closed-loop Diagram, thesis Ch. 14).

Not implemented yet; this package is their home."""
