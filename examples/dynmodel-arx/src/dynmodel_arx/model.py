"""The `arx` family: one linear difference equation per output,

    y_k(t) = c_k + sum_{i=1..na} a_{k,i} y_k(t-i) + sum_j sum_{m=0..nb-1} b_{k,j,m} u_j(t-nk-m),

i.e. A_k(q) y_k = B_k(q) u(t - nk) + c_k. With ``cost: mse1`` the weights minimize the one-step
(equation) error by least squares: the ARX model. With ``cost: mse_inf`` they are then re-estimated
on the free-running error (Levenberg-Marquardt, starting from the ARX weights with A made stable):
the output-error (OE) model, unbiased under output noise. The free run starts from rest (zeros in
model space, i.e. the training means), so no measured outputs are needed to start it.

Everything here uses only the public plugin contract (``dynmodel.family``): this package is an
example of a third-party family.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import lfilter

from dynmodel.data.training import TrainingData
from dynmodel.family import Family, Progress, Simulation, constructor_arguments, no_progress

from .params import ArxParams


def _lagged(x: np.ndarray, lags: range) -> np.ndarray:
    """Columns x(t - lag) for every lag, NaN before the first sample."""
    out = np.full((len(x), len(lags)), np.nan)
    for i, lag in enumerate(lags):
        out[lag:, i] = x[: len(x) - lag] if lag else x
    return out


def _stable(a: np.ndarray, margin: float = 0.98) -> np.ndarray:
    """a with the roots of A(z) = 1 - sum a_i z^-i moved inside the unit circle (reflected, then
    shrunk to ``margin`` when on it), so that the output-error search starts from a stable model."""
    if a.size == 0:
        return a
    roots = np.roots(np.concatenate([[1.0], -a]))
    big = np.abs(roots) >= margin
    if not big.any():
        return a
    roots[big] = margin * roots[big] / np.abs(roots[big])
    return -np.real(np.poly(roots))[1:]


class Arx(Family):
    name = "arx"
    description = (
        "linear ARX model (cost mse1: least squares on the equation error) or output-error model "
        "(cost mse_inf: free-running error), one difference equation per output"
    )
    Params = ArxParams
    stochastic = False
    stability_hint = "use cost: mse_inf (output error) or a lower na"

    params: ArxParams

    def __init__(
        self,
        *,
        na: int = 2,
        nb: int = 3,
        nk: int = 0,
        constant: bool = True,
        ridge: float = 0.0,
        max_nfev: int = 200,
    ) -> None:
        """Parameters as in ``ArxParams``; see the class help."""
        super().__init__(**constructor_arguments(locals()))

    # ------------------------------------------------------------------ fitting
    def _regressors(self, u: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Rows [y(t-1..na), u_j(t-nk..t-nk-nb+1) for every input j, 1] of one series and output."""
        p = self.params
        cols = [_lagged(y, range(1, p.na + 1))]
        cols += [_lagged(u[:, j], range(p.nk, p.nk + p.nb)) for j in range(u.shape[1])]
        if p.constant:
            cols.append(np.ones((len(y), 1)))
        return np.hstack(cols)

    def _split(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        p = self.params
        a = theta[: p.na]
        b = theta[p.na : p.na + p.nb * self.n_inputs_].reshape(self.n_inputs_, p.nb)
        return a, b, float(theta[-1]) if p.constant else 0.0

    def fit(
        self,
        data: TrainingData,
        cost: str = "mse1",
        rng: np.random.Generator | None = None,
        progress: Progress = no_progress,
    ) -> Arx:
        """Least squares on the training split (ARX); for cost mse_inf, then output error."""
        p = self.params
        self.n_inputs_, self.n_outputs_ = data.n_inputs, data.n_outputs
        self.a_ = np.zeros((self.n_outputs_, p.na))
        self.b_ = np.zeros((self.n_outputs_, self.n_inputs_, p.nb))
        self.c_ = np.zeros(self.n_outputs_)
        self.estimation_: list[dict[str, Any]] = []
        for k in range(self.n_outputs_):
            X = data.stack("train", [self._regressors(s.u, s.y[:, k]) for s in data.series])
            t = data.targets("train")[:, k]
            known = np.isfinite(X).all(axis=1) & np.isfinite(t)  # NaN: before a series starts, or test outputs
            X, t = X[known], t[known]
            if len(t) <= X.shape[1]:
                raise ValueError(
                    f"only {len(t)} training rows for {X.shape[1]} ARX weights; give more data or lower orders"
                )
            if p.ridge > 0:
                G = X.T @ X
                penalty = p.ridge * np.mean(np.diag(G)) * np.eye(len(G))
                if p.constant:
                    penalty[-1, -1] = 0.0
                theta = np.linalg.solve(G + penalty, X.T @ t)
            else:
                theta = np.linalg.lstsq(X, t, rcond=None)[0]
            info: dict[str, Any] = {"output": k, "rows": int(len(t)), "method": "arx"}
            if cost == "mse_inf":
                theta, info = self._output_error(data, k, theta, info)
                progress("output error", (k + 1) / self.n_outputs_, f"output {k + 1}: {info['nfev']} free runs")
            self.a_[k], self.b_[k], self.c_[k] = self._split(theta)
            self.estimation_.append(info)
        return self

    def _output_error(
        self, data: TrainingData, k: int, theta: np.ndarray, info: dict[str, Any]
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Re-estimate output k's weights on the free-running training error (from rest)."""
        p = self.params
        theta = theta.copy()
        theta[: p.na] = _stable(theta[: p.na])
        segments = data.segments["train"]

        def residuals(th: np.ndarray) -> np.ndarray:
            a, b, c = self._split(th)
            parts = []
            for s, lo, hi in segments:
                series = data.series[s]
                err = self._free_run(a, b, c, series.u[:hi])[lo:hi] - series.y[lo:hi, k]
                parts.append(err[np.isfinite(series.y[lo:hi, k])])
            return np.nan_to_num(np.concatenate(parts), nan=1e6, posinf=1e6, neginf=-1e6)

        with np.errstate(over="ignore", invalid="ignore"):
            res = least_squares(residuals, theta, method="lm", max_nfev=p.max_nfev, x_scale="jac")
        info.update(method="output error", nfev=int(res.nfev), cost=float(2 * res.cost), status=int(res.status))
        return res.x, info

    # ------------------------------------------------------------------ prediction
    def _free_run(self, a: np.ndarray, b: np.ndarray, c: float, u: np.ndarray) -> np.ndarray:
        """y(t) from rest (zero past) for one output: B(q)/A(q) u + c/A(q) 1."""
        p = self.params
        den = np.concatenate([[1.0], -a])
        y = lfilter([c], den, np.ones(len(u))) if c else np.zeros(len(u))
        for j in range(u.shape[1]):
            num = np.zeros(p.nk + p.nb)
            num[p.nk :] = b[j]
            y = y + lfilter(num, den, u[:, j])
        return y

    def simulate(
        self, u: np.ndarray, y_measured: np.ndarray | None = None, bounds: tuple[np.ndarray, np.ndarray] | None = None
    ) -> Simulation:
        self.check_fitted()
        u = np.asarray(u, dtype=np.float64).reshape(len(u), -1)
        with np.errstate(over="ignore", invalid="ignore"):
            y = np.column_stack([self._free_run(self.a_[k], self.b_[k], self.c_[k], u) for k in range(self.n_outputs_)])
            bad = ~np.isfinite(y)
            if bounds is not None:
                bad |= (y < bounds[0]) | (y > bounds[1])
        rows = np.flatnonzero(bad.any(axis=1))
        if rows.size == 0:
            return Simulation(y)
        y[rows[0] :] = np.nan
        return Simulation(y, int(rows[0]))

    def predict_one_step(self, u: np.ndarray, y_measured: np.ndarray) -> np.ndarray:
        """The equation's right-hand side with measured past outputs (zero before the first sample)."""
        self.check_fitted()
        u = np.asarray(u, dtype=np.float64).reshape(len(u), -1)
        y = np.asarray(y_measured, dtype=np.float64).reshape(len(u), -1)
        out = np.empty_like(y)
        for k in range(self.n_outputs_):
            pred = lfilter(np.concatenate([[0.0], self.a_[k]]), [1.0], y[:, k]) + self.c_[k]
            for j in range(u.shape[1]):
                num = np.zeros(self.params.nk + self.params.nb)
                num[self.params.nk :] = self.b_[k, j]
                pred = pred + lfilter(num, [1.0], u[:, j])
            out[:, k] = pred
        return out

    # ------------------------------------------------------------------ persistence
    def to_arrays(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        arrays = {"a": self.a_, "b": self.b_, "c": self.c_}
        return arrays, {"n_inputs": self.n_inputs_, "n_outputs": self.n_outputs_, "estimation": self.estimation_}

    @classmethod
    def from_arrays(cls, params: dict[str, Any], arrays: dict[str, np.ndarray], attrs: dict[str, Any]) -> Arx:
        self = cls(**params)
        self.n_inputs_, self.n_outputs_ = int(attrs["n_inputs"]), int(attrs["n_outputs"])
        p = self.params
        self.a_ = np.asarray(arrays["a"], dtype=np.float64).reshape(self.n_outputs_, p.na)
        self.b_ = np.asarray(arrays["b"], dtype=np.float64).reshape(self.n_outputs_, self.n_inputs_, p.nb)
        self.c_ = np.asarray(arrays["c"], dtype=np.float64).reshape(self.n_outputs_)
        self.estimation_ = list(attrs.get("estimation") or [])
        return self

    def summary(self) -> dict[str, Any]:
        info: dict[str, Any] = {"orders": f"na={self.params.na}, nb={self.params.nb}, nk={self.params.nk}"}
        for k in range(self.n_outputs_):
            poles = np.roots(np.concatenate([[1.0], -self.a_[k]])) if self.params.na else np.zeros(0)
            info[f"output {k}"] = {
                "estimation": self.estimation_[k]["method"] if k < len(self.estimation_) else None,
                "a": self.a_[k].tolist(),
                "largest |pole|": float(np.abs(poles).max()) if poles.size else 0.0,
            }
        return info
