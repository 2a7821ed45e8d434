"""Seam tracking (thesis Ch. 14): a particle filter over SE(3) fusing robot encoders (through the forward
kinematics and a compliance model) with laser stripes ahead of the tool, and its closed-loop simulation.

* :mod:`~drake_est.seam.seam` -- nominal seams (Fig. 14.9, CSV), validation, trend-filter compression (14.8);
* :mod:`~drake_est.seam.filter` -- the model callables (14.1)-(14.7) given to the generic ``ParticleFilter``;
* :mod:`~drake_est.seam.simulate` -- scenario (IK path, process force, compliance, kinematic errors) and the
  step-by-step loop the Drake Diagram (:mod:`drake_est.systems.seam`) reproduces;
* :mod:`~drake_est.seam.analysis` -- ``run_tracking`` (``drake-est track``), heat map (Fig. 14.5), sensor
  study (Fig. 14.8), parameter significance (Fig. 14.6), the animated Meshcat replay ``seam.html``;
* :mod:`~drake_est.seam.viz` -- what the replay and the live Meshcat draw (seam, laser stripes, tool,
  estimate, particle cloud).
"""
