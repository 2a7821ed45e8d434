"""LPV spectral estimation (thesis Ch. 10): spectra whose amplitude and phase depend on a
scheduling variable, on arbitrarily sampled data.

Frequencies are in cycles per unit of the sampling location (``omega = 2 pi f``); a
component is ``A cos(2 pi f x - phi)`` with complex coefficient ``k = A exp(i phi)``.

Main entry points
-----------------
* :class:`LPVSpectrum` -- LPV decomposition (10.4)-(10.8) with normalized basis (10.6), ridge,
  sign-split bases, power spectrum (10.22), Monte-Carlo confidence bands (Prop. 4, (10.19));
  direct / dual / matrix-free iterative solvers.
* :func:`lssa` -- least-squares spectrum (10.5); :func:`ls_scan` -- least-squares periodogram.
* :class:`SparseLPVSpectrum`, :func:`group_lasso_admm`, :func:`group_lasso_drake` -- L1 and
  group-lasso (10.20) spectra by ADMM, cross-checked with Drake's MathematicalProgram.
* :func:`find_periodic_components` -- detector of periodic components (e.g. motor-position
  ripple) without knowing the gear ratio.
* :mod:`~drake_est.spectral.classic` -- periodogram, Welch, Lomb-Scargle (scipy) for comparison.
"""
from drake_est.spectral.basis import ScheduleBasis
from drake_est.spectral.classic import lomb_scargle, periodogram, resample_uniform, top_peaks, welch
from drake_est.spectral.detect import PeriodicComponents, fft_scan, find_periodic_components
from drake_est.spectral.lpv import (LPVSpectrum, complex_normal_params, lssa, real_covariance_from_complex,
                                    sample_complex_normal)
from drake_est.spectral.lssa import (check_frequency_grid, frequency_grid, frequency_resolution, ls_scan,
                                     quantization_step, sampling_density_limit)
from drake_est.spectral.sparse import SparseLPVSpectrum, group_lasso_admm, group_lasso_drake

__all__ = [
    "ScheduleBasis", "LPVSpectrum", "SparseLPVSpectrum", "PeriodicComponents", "find_periodic_components",
    "fft_scan", "ls_scan", "lssa", "frequency_grid", "check_frequency_grid", "frequency_resolution",
    "quantization_step", "sampling_density_limit", "group_lasso_admm", "group_lasso_drake",
    "complex_normal_params", "real_covariance_from_complex", "sample_complex_normal",
    "periodogram", "welch", "lomb_scargle", "resample_uniform", "top_peaks",
]
