"""Figures for the LPV spectral method (thesis Figs. 10.2-10.3 and 10.5-10.6), matplotlib Agg."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def plot_scan(components, path, unit_scale: float = 1.0, unit_label: str = "cycles per rad", title=None,
              classic=None):
    """Least-squares LPV periodogram of the first scan with the found components marked (Fig. 10.5).

    ``classic=(x, r)``: add a lower panel with the periodogram and Welch estimates of ``r`` sorted by ``x``
    and interpolated onto a uniform grid (4 N points), as the thesis compares them."""
    plt = _plt()
    if classic is None:
        fig, ax = plt.subplots(figsize=(8, 4))
    else:
        fig, (ax, axc) = plt.subplots(2, 1, figsize=(8, 7))
    f = components.scan_freqs * unit_scale
    ax.plot(f, components.scan_power, lw=0.8, color="C0", label="LPV least-squares periodogram (one frequency at a time)")
    for c in range(components.n_components):
        ax.axvline(components.freqs[c] * unit_scale, color="C3", ls="--", lw=0.8)
        ax.annotate(f"{components.freqs[c] * unit_scale:.3g}", (components.freqs[c] * unit_scale,
                    components.scan_power.max() * (0.95 - 0.08 * c)), color="C3", fontsize=8)
    if f.size and f.min() > 0 and f.max() / f.min() > 100:
        ax.set_xscale("log")
    ax.set_xlabel(f"frequency [{unit_label}]")
    ax.set_ylabel("explained fraction of residual variance [-]")
    ax.set_title(title or "Spectrum of the signal in position (LPV least squares)")
    ax.legend(loc="upper right", fontsize=8)
    if classic is not None:
        from drake_est.spectral.classic import periodogram, welch

        xc, rc = classic
        n = 4 * len(xc)
        for est, lab in ((periodogram, "periodogram"), (welch, "Welch")):
            fc, Pc = est(xc, rc, n=n)
            keep = (fc > 0) & (fc <= components.scan_freqs.max())
            if not np.any(keep):      # e.g. coarsely quantized positions: no classic bin inside the scan range
                continue
            axc.plot(fc[keep] * unit_scale, Pc[keep] / max(Pc[keep].max(), 1e-300), lw=0.7, label=lab)
        for c in range(components.n_components):
            axc.axvline(components.freqs[c] * unit_scale, color="C3", ls="--", lw=0.8)
        if ax.get_xscale() == "log":
            axc.set_xscale("log")
        axc.set_xlim(ax.get_xlim())
        axc.set_xlabel(f"frequency [{unit_label}]")
        axc.set_ylabel("normalized PSD [-]")
        axc.set_title("Classic estimators on the sorted, interpolated residual (dashed: LPV components)")
        axc.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)


def plot_amplitude_functions(model, v_data, path, which=None, level: float = 0.95, labels=None,
                             v_label: str = "scheduling variable v", amp_label: str = "amplitude",
                             true_funcs=None, seed: int = 0, n_samples: int = 500, title=None):
    """Amplitude functions A(w, v) with Monte-Carlo confidence bands and the histogram of the
    schedule values in the data (Fig. 10.6); optional ``true_funcs`` (list of arrays on the grid)."""
    plt = _plt()
    v_data = np.asarray(v_data, dtype=float)
    lo, hi = np.quantile(v_data, [0.002, 0.998])
    vg = np.linspace(lo, hi, 200)
    which = np.arange(model.n_freqs) if which is None else np.atleast_1d(which)
    bands = model.confidence_bands(vg, level=level, n_samples=n_samples, seed=seed, which=which)
    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax2 = ax.twinx()
    ax2.hist(v_data, bins=60, color="0.85", zorder=0)
    ax2.set_ylabel("number of samples")
    ax.set_zorder(ax2.get_zorder() + 1)
    ax.patch.set_visible(False)
    for i, o in enumerate(which):
        lab = labels[i] if labels is not None else f"f = {model.freqs[o]:.4g}"
        ax.plot(vg, bands["amplitude"][i], color=f"C{i}", label=lab)
        ax.fill_between(vg, bands["amp_lo"][i], bands["amp_hi"][i], color=f"C{i}", alpha=0.25)
        if true_funcs is not None:
            ax.plot(vg, true_funcs[i](vg), color=f"C{i}", ls="--", lw=1)
    ax.set_xlabel(v_label)
    ax.set_ylabel(f"{amp_label} ({int(round(100 * level))} % band)")
    ax.set_title(title or "Amplitude functions A(f, v) with Monte-Carlo confidence bands")
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path), bands
