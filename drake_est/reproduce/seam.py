"""Reproductions for thesis Ch. 14 (seam tracking): seam-sensors (Fig. 14.8) and seam-significance (Fig. 14.6).

* ``seam-sensors``: estimation-error distributions (world x, y, z [mm]; tool-frame rotations [deg]) of the
  seam-tracking particle filter with 0, 1 and 2 laser stripes on the xy and yz seams of Fig. 14.9, over
  ``n_seeds`` runs each (20; quick: 4), the same filter parameters everywhere.  Thesis finding: y (the
  direction of motion) is poorly determined in every configuration; laser stripes improve the measurable
  directions; a single stripe cannot separate translation from rotation (Fig. 14.7).
* ``seam-significance``: Monte-Carlo runs with every filter parameter multiplied by a log-uniform factor in
  [1/3, 3]; linear models of each error on the log-factors; log10 p-values as a heat map (Fig. 14.6).

Runs use all local cores (processes) and show a progress bar.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from drake_est.seam.analysis import sensor_study, significance_study


def seam_sensors(out_dir, quick: bool = False, seed: int = 0, n_seeds: int | None = None, workers=None, **kw):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    n = n_seeds or (4 if quick else 20)
    particles = 200 if quick else 300
    res = sensor_study(n_seeds=n, particles=particles, quick=quick, workers=workers)
    labels = ["x [mm]", "y [mm]", "z [mm]", "rot x [deg]", "rot y [deg]", "rot z [deg]"]
    summary = {}
    fig, axes = plt.subplots(2, 6, figsize=(16, 6))
    for r, kind in enumerate(("xy", "yz")):
        for j, lab in enumerate(labels):
            data = []
            for s in (0, 1, 2):
                runs = res[f"{kind}_{s}"]
                v = np.array([(x["rms_xyz_mm"] + x["rms_rot_deg"])[j] for x in runs])
                data.append(v)
                summary.setdefault(f"{kind}_{s}_sensors", {})[lab] = {
                    "median": float(np.median(v)), "q10": float(np.percentile(v, 10)),
                    "q90": float(np.percentile(v, 90))}
            axes[r, j].boxplot(data)
            axes[r, j].set_xticks([1, 2, 3], ["0", "1", "2"])
            axes[r, j].set_title(f"{kind}: {lab}", fontsize=9)
            axes[r, j].set_xlabel("laser stripes")
    fig.suptitle("RMS estimation error over %d seeds (cf. thesis Fig. 14.8)" % n)
    fig.tight_layout()
    fig.savefig(out / "seam_sensors.png", dpi=80)
    plt.close(fig)
    cross = {k: float(np.median([x["metrics"]["estimate_cross_seam_rmse_mm"] for x in v])) for k, v in res.items()}
    return {"n_seeds": n, "particles": particles, "errors": summary, "median_estimate_cross_seam_rmse_mm": cross}


def seam_significance(out_dir, quick: bool = False, seed: int = 0, n_runs: int | None = None, workers=None, **kw):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    n = n_runs or (16 if quick else 60)
    res = significance_study(n_runs=n, particles=150 if quick else 300, quick=quick, seed=seed, workers=workers)
    L = np.array(res["log10_p"]).T          # errors x params
    fig, ax = plt.subplots(figsize=(9, 4))
    im = ax.imshow(np.maximum(L, -10), cmap="viridis_r", aspect="auto")
    ax.set_xticks(range(len(res["params"])), res["params"], rotation=30, ha="right")
    ax.set_yticks(range(len(res["errors"])), res["errors"])
    fig.colorbar(im, label="log10 p")
    ax.set_title(f"parameter significance, {n} runs (cf. thesis Fig. 14.6)")
    fig.tight_layout()
    fig.savefig(out / "seam_significance.png", dpi=80)
    plt.close(fig)
    res.pop("E")
    return res


EXPERIMENTS = {"seam-sensors": seam_sensors, "seam-significance": seam_significance}
