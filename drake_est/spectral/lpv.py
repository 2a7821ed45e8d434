"""LPV spectral decomposition (thesis Sec. 10.2, Eqs. (10.4)-(10.8), (10.19), (10.22)).

A signal sampled at arbitrary locations ``x`` (time, motor angle) with a scheduling
variable ``v`` (velocity) is modelled as

    y_n = sum_{w in Omega} Re( k_w^T phi_bar(v_n) exp(-i w x_n) ) + base_n^T beta + e_n

with normalized basis activations ``phi_bar`` (10.6).  With ``k = a + i b`` each term is
``(a^T phi_bar) cos(w x) + (b^T phi_bar) sin(w x)``, so the problem is a real least-squares
problem on ``[Re k, Im k]`` (the thesis' ``A_bar = [Re A, Im A]``), optionally with a ridge
penalty ``lam ||[a; b]||^2`` (base columns are not penalized).  Amplitude and phase
functions are ``A(w, v) = |k_w^T phi_bar(v)|`` (10.7) and ``phi(w, v) = arg(k_w^T phi_bar(v))``
(10.8), i.e. the component reads ``A cos(w x - phi)``.

Solvers (``solver="auto"``):

* ``"direct"`` (at most ``direct_max`` real parameters, default 2000): normal equations
  accumulated over row chunks and a Cholesky factorization; gives the posterior
  covariance ``sigma^2 (A^T A + lam I)^-1`` (10.19) used for confidence bands.
* ``"dual"`` (more parameters than samples, ``lam > 0``, N <= ``dual_max``): the kernel form
  ``theta = A^T (A A^T + lam I)^-1 y``; the per-frequency covariance blocks follow from the
  Woodbury identity.
* ``"iterative"`` (otherwise): matrix-free conjugate gradients on the normal equations with a
  block-Jacobi preconditioner (one exact 2J x 2J block per frequency); no covariance (confidence
  bands raise :class:`DrakeEstError`).

Without a ridge penalty, fewer samples than parameters raise :class:`IdentifiabilityError`.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse.linalg

from drake_est.errors import DataError, DrakeEstError, IdentifiabilityError
from drake_est.spectral.basis import ScheduleBasis
from drake_est.spectral.lssa import _clean_1d, check_frequency_grid


# --------------------------------------------------------------------------- complex normal (10.19), Prop. 4

def complex_normal_params(Sigma: np.ndarray):
    """Covariance ``Gamma`` and relation ``C`` of the complex-normal distribution of
    ``z = x + i y`` from the real covariance ``Sigma`` of ``[x; y]`` (Eq. (10.19))."""
    Sigma = np.asarray(Sigma, dtype=float)
    D = Sigma.shape[0] // 2
    Srr, Sri = Sigma[:D, :D], Sigma[:D, D:]
    Sir, Sii = Sigma[D:, :D], Sigma[D:, D:]
    Gamma = Srr + Sii + 1j * (Sir - Sri)
    C = Srr - Sii + 1j * (Sir + Sri)
    return Gamma, C


def real_covariance_from_complex(Gamma, C) -> np.ndarray:
    """The real ``2D x 2D`` covariance of ``[Re z; Im z]`` for ``z ~ CN(0, Gamma, C)`` (Prop. 4)."""
    Gamma = np.asarray(Gamma)
    C = np.asarray(C)
    return 0.5 * np.block([[np.real(Gamma + C), np.imag(-Gamma + C)],
                           [np.imag(Gamma + C), np.real(Gamma - C)]])


def sample_complex_normal(mean, Gamma, C, n: int, rng=None) -> np.ndarray:
    """``n`` samples (n, D) of ``CN(mean, Gamma, C)`` by Proposition 4: ``[Re; Im] = L z`` with
    ``L L^T`` the Cholesky factorization of the real covariance and ``z ~ N(0, I)``."""
    rng = np.random.default_rng(rng)
    S = real_covariance_from_complex(Gamma, C)
    D = S.shape[0] // 2
    S = 0.5 * (S + S.T)
    jitter = 1e-12 * max(float(np.trace(S)) / (2 * D), 1e-300)
    L = np.linalg.cholesky(S + jitter * np.eye(2 * D))
    z = rng.standard_normal((n, 2 * D))
    r = z @ L.T
    return np.asarray(mean)[None, :] + r[:, :D] + 1j * r[:, D:]


# --------------------------------------------------------------------------- estimator


class LPVSpectrum:
    """LPV spectral decomposition on a frequency grid (cycles per unit of x).

    Parameters
    ----------
    freqs : frequency grid, cycles per unit of ``x`` (omega = 2 pi f).
    n_basis : J, number of normalized Gaussian basis functions over the schedule
        (1: plain least-squares spectrum (10.5), no schedule needed).
    sign_split : Coulomb-style split of the basis at v = 0 (Sec. 10.3).
    lam : ridge penalty on the spectral coefficients.
    basis : a ready :class:`ScheduleBasis` (overrides n_basis/sign_split).
    solver : "auto" | "direct" | "dual" | "iterative".
    direct_max : largest number of real parameters solved directly when ``solver="auto"``.
    check_grid : validate the grid against the sampling density of ``x``.
    """

    def __init__(self, freqs, n_basis: int = 10, sign_split: bool = False, lam: float = 0.0, basis=None,
                 width_factor: float = 1.0, solver: str = "auto", direct_max: int = 2000, dual_max: int = 6000,
                 check_grid: bool = True, iter_tol: float = 1e-8, iter_max: int | None = None):
        self.freqs = np.atleast_1d(np.asarray(freqs, dtype=float)).ravel()
        self.n_basis = int(basis.n_basis if basis is not None else n_basis)
        self.sign_split = sign_split
        self.lam = float(lam)
        if self.lam < 0:
            raise DataError(f"ridge penalty must be >= 0, got {lam}")
        self.basis = basis
        self.width_factor = width_factor
        if solver not in ("auto", "direct", "dual", "iterative"):
            raise DataError(f"unknown solver '{solver}'; choose auto, direct, dual or iterative")
        self.solver = solver
        self.direct_max = int(direct_max)
        self.dual_max = int(dual_max)
        self.check_grid = check_grid
        self.iter_tol = iter_tol
        self.iter_max = iter_max

    # ------------------------------------------------------------------ helpers
    @property
    def n_freqs(self) -> int:
        return self.freqs.size

    @property
    def n_spectral_params(self) -> int:
        return 2 * self.n_freqs * self.n_basis

    def _phi(self, v, N):
        if self.basis.n_basis == 1:
            return np.ones((N, 1))
        if v is None:
            raise DataError(f"the LPV spectrum with {self.basis.n_basis} basis functions needs the scheduling variable")
        v = _clean_1d(v, "scheduling variable")
        if v.size != N:
            raise DataError(f"scheduling variable has {v.size} samples, sample locations {N}")
        return self.basis(v)

    def _trig(self, x):
        arg = np.outer(x, 2 * np.pi * self.freqs)
        return np.cos(arg), np.sin(arg)

    @staticmethod
    def _design_rows(Phi, C, S, base):
        N, J = Phi.shape
        O = C.shape[1]
        A = np.empty((N, O, 2, J))
        A[:, :, 0, :] = C[:, :, None] * Phi[:, None, :]
        A[:, :, 1, :] = S[:, :, None] * Phi[:, None, :]
        A = A.reshape(N, O * 2 * J)
        if base is not None:
            A = np.hstack([A, base])
        return A

    def regressor(self, x, v=None, base=None) -> np.ndarray:
        """Real regressor matrix (N, 2 O J [+ n_base]); columns ordered frequency-major,
        ``[phi cos(w_o x), phi sin(w_o x)]`` for each ``o``, then the base columns."""
        x = _clean_1d(x, "sample locations")
        Phi = self._phi(v, x.size)
        C, S = self._trig(x)
        return self._design_rows(Phi, C, S, None if base is None else np.asarray(base, float).reshape(x.size, -1))

    # ------------------------------------------------------------------ fit
    def fit(self, x, y, v=None, base=None):
        """Estimate the coefficients from samples ``y`` at locations ``x`` with schedule ``v``.
        ``base`` (N, b) are extra unpenalized regressors fitted jointly (e.g. friction terms)."""
        x = _clean_1d(x, "sample locations")
        y = _clean_1d(y, "signal")
        N = x.size
        if y.size != N:
            raise DataError(f"signal has {y.size} samples, sample locations {N}")
        if self.basis is None:
            if self.n_basis == 1:
                self.basis = ScheduleBasis(1)
            else:
                if v is None:
                    raise DataError(f"the LPV spectrum with {self.n_basis} basis functions needs the scheduling variable")
                self.basis = ScheduleBasis.from_data(v, self.n_basis, sign_split=self.sign_split,
                                                     width_factor=self.width_factor)
        if self.check_grid:
            check_frequency_grid(x, self.freqs)
        Phi = self._phi(v, N)
        if base is not None:
            base = np.asarray(base, dtype=float).reshape(N, -1)
            if not np.all(np.isfinite(base)):
                raise DataError("base regressors contain NaN/inf")
        nb = 0 if base is None else base.shape[1]
        p_spec = self.n_spectral_params
        p = p_spec + nb
        dead = np.flatnonzero(np.abs(Phi).sum(axis=0) <= 1e-12 * N)
        if dead.size and self.lam == 0:
            raise IdentifiabilityError(
                f"schedule basis function(s) {dead.tolist()} (centres {np.round(self.basis.centers[dead], 4).tolist()}) "
                "have no data; use fewer basis functions or a ridge penalty")
        if N < p and self.lam == 0:
            raise IdentifiabilityError(
                f"{N} samples are fewer than the {p} real parameters (2 x {self.n_freqs} frequencies x "
                f"{self.n_basis} basis functions{f' + {nb} base' if nb else ''}); use fewer frequencies/basis "
                "functions or a ridge penalty lam > 0")
        solver = self.solver
        if solver == "auto":
            if p <= self.direct_max:
                solver = "direct"
            elif p > N and N <= self.dual_max and self.lam > 0:
                solver = "dual"
            else:
                solver = "iterative"
        if solver == "dual" and self.lam <= 0:
            raise DataError("the dual (kernel) solver needs a ridge penalty lam > 0")
        pen = np.r_[np.ones(p_spec), np.zeros(nb)]
        self._cov_state = None
        if solver == "direct":
            theta = self._solve_direct(x, y, Phi, base, pen)
        elif solver == "dual":
            theta = self._solve_dual(x, y, Phi, base, pen)
        else:
            theta = self._solve_iterative(x, y, Phi, base)
        self.solver_used = solver
        self.theta = theta
        self.coef = theta[:p_spec].reshape(self.n_freqs, 2, self.n_basis)
        self.coef = self.coef[:, 0, :] + 1j * self.coef[:, 1, :]
        self.base_coef = theta[p_spec:]
        if solver == "direct":
            self.rss = max(self._rss_direct, 0.0)
        else:
            resid = y - self._apply(x, Phi, base, theta)
            self.rss = float(resid @ resid)
        self.n_samples = N
        self.tss = float(np.sum((y - y.mean()) ** 2))
        self.sumsq = float(y @ y)
        dof = getattr(self, "dof", float(p))
        self.sigma2 = self.rss / max(N - dof, 1.0)
        self._v_range = (None if v is None else (float(np.min(v)), float(np.max(v))))
        return self

    def _chunks(self, N, p):
        rows = max(64, int(6e6 // max(p, 1)))
        return range(0, N, rows), rows

    def _solve_direct(self, x, y, Phi, base, pen):
        N = x.size
        p = self.n_spectral_params + (0 if base is None else base.shape[1])
        if self._uniform_grid() and self.n_freqs > 2:
            G, b = self._gram_uniform(x, y, Phi, base)
        else:
            G = np.zeros((p, p))
            b = np.zeros(p)
            starts, rows = self._chunks(N, p)
            for s in starts:
                sl = slice(s, s + rows)
                C, S = self._trig(x[sl])
                A = self._design_rows(Phi[sl], C, S, None if base is None else base[sl])
                G += A.T @ A
                b += A.T @ y[sl]
        scale = max(float(np.mean(np.diag(G))), 1e-300)
        H = G + self.lam * np.diag(pen)
        try:
            cf = scipy.linalg.cho_factor(H, lower=False, check_finite=False)
            ok = np.all(np.diag(cf[0]) > np.sqrt(scale) * 1e-7)
        except np.linalg.LinAlgError:
            ok = False
        if not ok:
            self._raise_unidentifiable(G, pen)
        theta = scipy.linalg.cho_solve(cf, b, check_finite=False)
        if self.lam > 0:
            # effective number of parameters tr(G H^-1) = p - lam tr(D H^-1), H = R^T R
            Rinv_t = scipy.linalg.solve_triangular(cf[0], np.diag(np.sqrt(pen)), trans="T", lower=False,
                                                   check_finite=False)
            self.dof = float(p - self.lam * np.sum(Rinv_t**2))
        else:
            self.dof = float(p)
        self._cov_state = ("direct", cf)
        # residual sum of squares from the normal equations (no second pass over the data)
        self._rss_direct = float(y @ y - 2 * theta @ b + theta @ (G @ theta))
        return theta

    def _uniform_grid(self) -> bool:
        f = self.freqs
        if f.size < 2:
            return False
        d = np.diff(f)
        return bool(d[0] > 0 and np.allclose(d, d[0], rtol=1e-9, atol=0.0))

    def _gram_uniform(self, x, y, Phi, base):
        """``A^T A`` and ``A^T y`` for a uniform grid ``f_o = f_0 + o df`` without forming ``A``.

        Products of sinusoids are sinusoids at the difference ``(o - o') df`` and the sum
        ``2 f_0 + (o + o') df`` frequencies, so all (2OJ)^2 Gram entries follow from the
        pair products ``phi_i phi_j`` weighted by 3O - 1 cosines and sines: O(N J^2 O) work
        instead of O(N J^2 O^2)."""
        from drake_est.spectral.lssa import _pair_products

        N, J = Phi.shape
        O = self.n_freqs
        f0, df = self.freqs[0], self.freqs[1] - self.freqs[0]
        PP, iu = _pair_products(Phi)
        npair = PP.shape[1]
        fd = df * np.arange(O)                     # difference frequencies (|o - o'|)
        fs = 2 * f0 + df * np.arange(2 * O - 1)    # sum frequencies (o + o')
        allf = np.r_[fd, fs]
        Wc = np.empty((allf.size, npair))
        Ws = np.empty((allf.size, npair))
        ch = max(1, int(4e6 // max(N, 1)))
        for s0 in range(0, allf.size, ch):
            arg = np.outer(x, 2 * np.pi * allf[s0:s0 + ch])
            Wc[s0:s0 + ch] = (PP.T @ np.cos(arg)).T
            Ws[s0:s0 + ch] = (PP.T @ np.sin(arg)).T

        def sym(vals):
            M = np.zeros(vals.shape[:-1] + (J, J))
            M[..., iu[0], iu[1]] = vals
            M[..., iu[1], iu[0]] = vals
            return M

        Dc, Ds = sym(Wc[:O]), sym(Ws[:O])
        Sc, Ss = sym(Wc[O:]), sym(Ws[O:])
        o = np.arange(O)
        dd = np.abs(o[:, None] - o[None, :])
        ss = o[:, None] + o[None, :]
        sg = np.sign(o[:, None] - o[None, :]).astype(float)[..., None, None]
        G4 = np.empty((O, 2, J, O, 2, J))
        cc = 0.5 * (Dc[dd] + Sc[ss])                 # (O, O, J, J): sum phi phi cos(a) cos(b)
        sn = 0.5 * (Dc[dd] - Sc[ss])                 # sin(a) sin(b)
        cs = 0.5 * (Ss[ss] - sg * Ds[dd])            # cos(a) sin(b), a = w_o x, b = w_o' x
        G4[:, 0, :, :, 0, :] = cc.transpose(0, 2, 1, 3)
        G4[:, 1, :, :, 1, :] = sn.transpose(0, 2, 1, 3)
        G4[:, 0, :, :, 1, :] = cs.transpose(0, 2, 1, 3)
        G4[:, 1, :, :, 0, :] = cs.transpose(1, 3, 0, 2)
        ps = 2 * O * J
        nb = 0 if base is None else base.shape[1]
        G = np.empty((ps + nb, ps + nb))
        G[:ps, :ps] = G4.reshape(ps, ps)
        b = np.empty(ps + nb)
        Py = Phi * y[:, None]
        for s0 in range(0, O, ch):
            arg = np.outer(x, 2 * np.pi * self.freqs[s0:s0 + ch])
            C, S = np.cos(arg), np.sin(arg)
            bb = np.stack([(Py.T @ C).T, (Py.T @ S).T], axis=1)        # (o, 2, J)
            b[s0 * 2 * J:(s0 + C.shape[1]) * 2 * J] = bb.ravel()
            if nb:
                Ab = np.empty((N, C.shape[1], 2, J))
                Ab[:, :, 0, :] = C[:, :, None] * Phi[:, None, :]
                Ab[:, :, 1, :] = S[:, :, None] * Phi[:, None, :]
                cross = base.T @ Ab.reshape(N, -1)
                G[ps:, s0 * 2 * J:(s0 + C.shape[1]) * 2 * J] = cross
                G[s0 * 2 * J:(s0 + C.shape[1]) * 2 * J, ps:] = cross.T
        if nb:
            G[ps:, ps:] = base.T @ base
            b[ps:] = base.T @ y
        return G, b

    def _raise_unidentifiable(self, G, pen):
        d = np.sqrt(np.maximum(np.diag(G), 1e-300))
        Gs = G / np.outer(d, d) + self.lam * np.diag(pen / d**2)
        w, V = np.linalg.eigh(Gs)
        vec = V[:, 0]
        i = int(np.argmax(np.abs(vec)))
        J = self.n_basis
        if i < self.n_spectral_params:
            o, rest = divmod(i, 2 * J)
            what = f"frequency {self.freqs[o]:.6g} ({'cos' if rest < J else 'sin'}, basis {rest % J})"
        else:
            what = f"base column {i - self.n_spectral_params}"
        raise IdentifiabilityError(
            f"LPV spectral regressors are linearly dependent (condition ~{w[-1] / max(w[0], 1e-300):.1e}); "
            f"the data do not excite {what} -- drop frequencies that the data cannot separate "
            "(grid finer than 1/span, or near the sampling-density limit) or add a ridge penalty")

    def _solve_dual(self, x, y, Phi, base, pen):
        if base is not None and base.shape[1]:
            raise DrakeEstError("the dual solver does not support base regressors; use solver='iterative'")
        A = self.regressor_from(x, Phi)
        K = A @ A.T
        K[np.diag_indices_from(K)] += self.lam
        cf = scipy.linalg.cho_factor(K, lower=False, check_finite=False)
        alpha = scipy.linalg.cho_solve(cf, y, check_finite=False)
        theta = A.T @ alpha
        # dof = tr(K0 (K0 + lam I)^-1) = N - lam tr((K0 + lam I)^-1)
        self.dof = float(K.shape[0] - self.lam *
                         np.trace(scipy.linalg.cho_solve(cf, np.eye(K.shape[0]), check_finite=False)))
        self._cov_state = ("dual", cf, A)
        return theta

    def regressor_from(self, x, Phi):
        C, S = self._trig(x)
        return self._design_rows(Phi, C, S, None)

    def _operator(self, x, Phi, base):
        N, J = Phi.shape
        O = self.n_freqs
        nb = 0 if base is None else base.shape[1]
        p = 2 * O * J + nb
        cache = N * O <= 3e7
        CS = self._trig(x) if cache else None
        ochunk = max(1, int(4e6 // max(N, 1)))

        def trig_blocks():
            if cache:
                yield slice(0, O), CS[0], CS[1]
            else:
                for s in range(0, O, ochunk):
                    arg = np.outer(x, 2 * np.pi * self.freqs[s:s + ochunk])
                    yield slice(s, s + ochunk), np.cos(arg), np.sin(arg)

        def matvec(th):
            th = np.asarray(th).ravel()
            T = th[:2 * O * J].reshape(O, 2, J)
            out = np.zeros(N)
            for sl, C, S in trig_blocks():
                Kc = Phi @ T[sl, 0, :].T
                Ks = Phi @ T[sl, 1, :].T
                out += np.sum(Kc * C + Ks * S, axis=1)
            if nb:
                out += base @ th[2 * O * J:]
            return out

        def rmatvec(r):
            r = np.asarray(r).ravel()
            T = np.empty((O, 2, J))
            Pr = Phi * r[:, None]
            for sl, C, S in trig_blocks():
                T[sl, 0, :] = (Pr.T @ C).T
                T[sl, 1, :] = (Pr.T @ S).T
            out = T.ravel()
            if nb:
                out = np.r_[out, base.T @ r]
            return out

        return scipy.sparse.linalg.LinearOperator((N, p), matvec=matvec, rmatvec=rmatvec, dtype=float)

    def _solve_iterative(self, x, y, Phi, base):
        """Preconditioned conjugate gradients on the normal equations, matrix-free.

        Preconditioner: block Jacobi with one exact (2J x 2J) Gram block per frequency (frequencies
        of a grid spaced at least the resolution 1/span apart are nearly orthogonal), computed with
        the pair-product trick ``phi_i phi_j cos^2 = phi_i phi_j (1 + cos 2wx) / 2``."""
        from drake_est.spectral.lssa import _pair_products

        op = self._operator(x, Phi, base)
        N, J = Phi.shape
        O = self.n_freqs
        nb = 0 if base is None else base.shape[1]
        PP, iu = _pair_products(Phi)
        m0 = PP.sum(axis=0)
        mc = np.empty((O, PP.shape[1]))
        ms = np.empty((O, PP.shape[1]))
        ochunk = max(1, int(4e6 // max(N, 1)))
        for s0 in range(0, O, ochunk):
            arg = np.outer(x, 2 * np.pi * self.freqs[s0:s0 + ochunk])
            C, S = np.cos(arg), np.sin(arg)
            mc[s0:s0 + ochunk] = (PP.T @ (C * C - S * S)).T
            ms[s0:s0 + ochunk] = (PP.T @ (2.0 * C * S)).T

        def sym(vals):
            M = np.zeros((vals.shape[0], J, J))
            M[:, iu[0], iu[1]] = vals
            M[:, iu[1], iu[0]] = vals
            return M

        M0, Mc, Ms = sym(m0[None])[0], sym(mc), sym(ms)
        G = np.empty((O, 2 * J, 2 * J))
        G[:, :J, :J] = 0.5 * (M0[None] + Mc)
        G[:, J:, J:] = 0.5 * (M0[None] - Mc)
        G[:, :J, J:] = 0.5 * Ms
        G[:, J:, :J] = 0.5 * Ms
        scale = max(float(np.mean(np.trace(G, axis1=1, axis2=2))) / (2 * J), 1e-300)
        G += (self.lam + 1e-10 * scale) * np.eye(2 * J)[None]
        Gb = None if not nb else base.T @ base + 1e-10 * scale * np.eye(nb)
        pen = np.r_[np.ones(2 * O * J), np.zeros(nb)]
        p = pen.size

        def precond(r):
            r = np.asarray(r).ravel()
            out = np.empty(p)
            out[:2 * O * J] = np.linalg.solve(G, r[:2 * O * J].reshape(O, 2 * J, 1)).ravel()
            if nb:
                out[2 * O * J:] = np.linalg.solve(Gb, r[2 * O * J:])
            return out

        normal = scipy.sparse.linalg.LinearOperator(
            (p, p), matvec=lambda th: op.rmatvec(op.matvec(th)) + self.lam * pen * np.ravel(th), dtype=float)
        Minv = scipy.sparse.linalg.LinearOperator((p, p), matvec=precond, dtype=float)
        rhs = op.rmatvec(y)
        count = [0]

        def cb(_):
            count[0] += 1

        maxiter = self.iter_max or 500
        theta, info = scipy.sparse.linalg.cg(normal, rhs, rtol=self.iter_tol, maxiter=maxiter, M=Minv, callback=cb)
        self.iterative_info = {"method": "block-Jacobi PCG on the normal equations", "iterations": count[0],
                               "converged": info == 0}
        if info != 0:
            import warnings

            warnings.warn(f"LPV iterative solver stopped after {count[0]} iterations without reaching rtol "
                          f"{self.iter_tol:g}; the grid may hold nearly collinear frequencies", RuntimeWarning,
                          stacklevel=3)
        self.dof = float(min(op.shape))
        return theta

    def _apply(self, x, Phi, base, theta):
        return self._operator(x, Phi, base).matvec(theta)

    # ------------------------------------------------------------------ use
    def predict(self, x, v=None, base=None, which=None) -> np.ndarray:
        """Model output at ``x``, ``v`` (+ base); ``which``: indices of frequencies to include."""
        x = _clean_1d(x, "sample locations")
        Phi = self._phi(v, x.size)
        K = Phi @ self.coef.T                                  # (N, O) complex amplitude at v
        arg = np.outer(x, 2 * np.pi * self.freqs)
        comp = np.real(K) * np.cos(arg) + np.imag(K) * np.sin(arg)
        if which is not None:
            comp = comp[:, np.atleast_1d(which)]
        out = comp.sum(axis=1)
        if base is not None and self.base_coef.size:
            out = out + np.asarray(base, float).reshape(x.size, -1) @ self.base_coef
        return out

    def complex_amplitude(self, v=None) -> np.ndarray:
        """``k_w^T phi_bar(v)`` (O, M) for schedule values ``v`` (M,)."""
        v = np.atleast_1d(np.asarray(v if v is not None else [0.0], dtype=float))
        Phi = self.basis(v) if self.basis.n_basis > 1 else np.ones((v.size, 1))
        return self.coef @ Phi.T

    def amplitude(self, v=None) -> np.ndarray:
        """Amplitude functions ``A(w, v)`` (10.7), shape (O, M)."""
        return np.abs(self.complex_amplitude(v))

    def phase(self, v=None) -> np.ndarray:
        """Phase functions ``phi(w, v)`` (10.8) in rad, shape (O, M); the component is A cos(w x - phi)."""
        return np.angle(self.complex_amplitude(v))

    def power_spectrum(self, kind: str = "thesis", v=None) -> np.ndarray:
        """Power per frequency.

        ``"thesis"``: Eq. (10.22) scaled by 1/J^2, ``|mean_j k_wj|^2`` (amplitude^2 of the
        coefficient averaged over the basis, i.e. over the schedule range);
        ``"data"``: mean over the schedule values ``v`` (e.g. the data) of ``A(w, v)^2``."""
        if kind == "thesis":
            return np.abs(self.coef.mean(axis=1)) ** 2
        if kind == "data":
            if v is None and self.basis.n_basis > 1:
                raise DataError("power_spectrum(kind='data') needs the schedule values v")
            return np.mean(self.amplitude(v) ** 2, axis=1)
        raise DataError(f"unknown power-spectrum kind '{kind}'; use 'thesis' or 'data'")

    def explained_fraction(self) -> float:
        """1 - RSS / sum(y^2) of the fit (signal energy explained, including base columns)."""
        return 1.0 - self.rss / max(self.sumsq, 1e-300)

    # ------------------------------------------------------------------ uncertainty
    def _indices(self, o):
        J = self.n_basis
        return np.arange(o * 2 * J, (o + 1) * 2 * J)

    def covariance_block(self, o: int) -> np.ndarray:
        """Posterior covariance (2J, 2J) of ``[Re k_o; Im k_o]`` (10.19): ``sigma^2 (A^T A + lam I)^-1``."""
        st = getattr(self, "_cov_state", None)
        if st is None:
            raise DrakeEstError(f"covariance is not available from the '{self.solver_used}' solver; refit with "
                                "solver='direct' (or fewer parameters) for confidence bands")
        idx = self._indices(o)
        if st[0] == "direct":
            p = st[1][0].shape[0]
            E = np.zeros((p, idx.size))
            E[idx, np.arange(idx.size)] = 1.0
            S = scipy.linalg.cho_solve(st[1], E, check_finite=False)[idx]
        else:
            _, cf, A = st
            Ao = A[:, idx]
            S = (np.eye(idx.size) - Ao.T @ scipy.linalg.cho_solve(cf, Ao, check_finite=False)) / self.lam
        return self.sigma2 * 0.5 * (S + S.T)

    def sample_coefficients(self, o: int, n: int = 1000, seed=0) -> np.ndarray:
        """``n`` posterior samples of ``k_o`` (n, J) drawn from CN(k_o, Gamma, C) (Prop. 4, Eq. (10.19))."""
        Sig = self.covariance_block(o)
        J = self.n_basis
        # our ordering is [Re k; Im k] already
        Gamma, C = complex_normal_params(Sig)
        return sample_complex_normal(self.coef[o], Gamma, C, n, rng=seed)

    def confidence_bands(self, v, level: float = 0.95, n_samples: int = 1000, seed=0, which=None,
                         method: str = "region") -> dict:
        """Monte-Carlo confidence bands of ``A(w, v)`` and ``phi(w, v)``: posterior samples of the
        coefficients (Prop. 4, Eq. (10.19)) pushed through (10.7)-(10.8).

        ``method="percentile"`` (the thesis' recipe): pointwise percentiles of the sampled
        ``|z|`` and ``arg z`` with ``z = k^T phi_bar(v)``.  Near ``A = 0`` these bands exclude the
        truth because ``|z|`` is biased upward (Prop. 3, Eq. (10.11)).
        ``method="region"`` (default): the range of ``|z|`` and ``arg z`` over the samples inside
        the ``level`` posterior region of the complex amplitude ``z`` (smallest Mahalanobis
        distances); the lower amplitude bound is 0 and the phase band is (-pi, pi] when that
        region contains the origin.  Covers the true amplitude whenever the region covers the true
        ``z``, so its coverage is at least ``level`` (conservative).

        Returns a dict of arrays (O', M): ``amplitude``, ``amp_lo``, ``amp_hi``, ``phase``,
        ``phase_lo``, ``phase_hi``, and ``freqs``, ``v``, ``level``, ``method``."""
        if method not in ("region", "percentile"):
            raise DataError(f"unknown band method '{method}'; use 'region' or 'percentile'")
        if not 0 < level < 1:
            raise DataError(f"confidence level must be in (0, 1), got {level}")
        v = np.atleast_1d(np.asarray(v, dtype=float))
        which = np.arange(self.n_freqs) if which is None else np.atleast_1d(which)
        Phi = self.basis(v) if self.basis.n_basis > 1 else np.ones((v.size, 1))
        J = self.n_basis
        lo_q, hi_q = 50 * (1 - level), 50 * (1 + level)
        out = {k: [] for k in ("amplitude", "amp_lo", "amp_hi", "phase", "phase_lo", "phase_hi")}
        for o in which:
            o = int(o)
            ks = self.sample_coefficients(o, n_samples, seed=np.random.default_rng([seed, o]))
            za = ks @ Phi.T                                  # (n, M)
            z0 = self.coef[o] @ Phi.T
            amp = np.abs(za)
            ph = np.angle(za * np.conj(z0)[None, :]) + np.angle(z0)[None, :]   # unwrapped around the estimate
            out["amplitude"].append(np.abs(z0))
            out["phase"].append(np.angle(z0))
            if method == "percentile":
                out["amp_lo"].append(np.percentile(amp, lo_q, axis=0))
                out["amp_hi"].append(np.percentile(amp, hi_q, axis=0))
                out["phase_lo"].append(np.percentile(ph, lo_q, axis=0))
                out["phase_hi"].append(np.percentile(ph, hi_q, axis=0))
                continue
            Sig = self.covariance_block(o)
            Srr, Sri, Sii = Sig[:J, :J], Sig[:J, J:], Sig[J:, J:]
            a = np.einsum("mj,jk,mk->m", Phi, Srr, Phi)
            b = np.einsum("mj,jk,mk->m", Phi, Sri, Phi)
            c = np.einsum("mj,jk,mk->m", Phi, Sii, Phi)
            det = np.maximum(a * c - b * b, 1e-300)

            def maha(dr, di):
                return (c * dr * dr - 2 * b * dr * di + a * di * di) / det

            d = maha(za.real - z0.real[None], za.imag - z0.imag[None])       # (n, M)
            thr = np.quantile(d, level, axis=0)
            inside = d <= thr[None]
            amp_in = np.where(inside, amp, np.nan)
            ph_in = np.where(inside, ph, np.nan)
            origin_in = maha(-z0.real, -z0.imag) <= thr
            alo = np.nanmin(amp_in, axis=0)
            out["amp_lo"].append(np.where(origin_in, 0.0, alo))
            out["amp_hi"].append(np.nanmax(amp_in, axis=0))
            out["phase_lo"].append(np.where(origin_in, -np.pi, np.nanmin(ph_in, axis=0)))
            out["phase_hi"].append(np.where(origin_in, np.pi, np.nanmax(ph_in, axis=0)))
        res = {k: np.array(val) for k, val in out.items()}
        res["freqs"] = self.freqs[which]
        res["v"] = v
        res["level"] = level
        res["method"] = method
        return res

    def dominant(self, n: int = 3, kind: str = "thesis", v=None):
        """Indices of the ``n`` largest components of the power spectrum (descending)."""
        P = self.power_spectrum(kind, v)
        return np.argsort(-P)[:n]


def lssa(x, y, freqs, lam: float = 0.0):
    """Joint least-squares spectrum (10.5) of ``y`` sampled at arbitrary ``x`` on the grid ``freqs``
    (cycles per unit x).  Returns a fitted :class:`LPVSpectrum` with one constant basis function; its
    ``.coef[:, 0]`` are the complex Fourier coefficients ``k``."""
    return LPVSpectrum(freqs, n_basis=1, lam=lam).fit(x, y)
