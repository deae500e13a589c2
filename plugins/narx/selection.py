"""Structure selection on the free-running error (``selection: free_run``).

Thesis 3.1.4 / 3.2.5: FOS scores every candidate by its one-step error reduction, which noise in
the fed-back outputs biases, and a term's worth in a *free* run depends on the other terms
(fig. 3.5), so MSE_inf admits no exact one-by-one selection. This module selects by the
linearised free-running error instead. Around the current model (weights w, free run yhat) a
candidate monomial c added with a small weight v changes the free run by v * s_c, where s_c is
its forward sensitivity on the free-run trajectory (:func:`kernels.candidate_sensitivities`).
The Gauss-Newton error reduction of adding c, with the current weights free to adjust, is
FOS's Q of candidate c on the target r = y - yhat after the current terms' sensitivity columns
(= the Jacobian) are forced in: so each step is one call of :func:`regression.fos_select` on the
Gram matrix of the sensitivity columns. The chosen term enters with weight 0, all weights are
re-estimated on the free-running error (nonlinear least squares), and the loop stops at
``max_terms``, at ``threshold``, or when the free-running validation error has not reached a
new low for ``patience`` terms (A.3); the best model on validation is kept.

The growth starts from the linear (ARX) model that validates best (``free_run_start: linear``,
see :func:`_linear_start`): around a constant model every fed-back term is invisible (the
linearisation is degenerate), so a growth from the constant alone stops there on most measured
systems. A current term whose sensitivity falls numerically into the span of the others (an
integrator's y[t-1] and y[t-2]) is skipped by the forced selection instead of ending the growth.

The growth runs on at most ``growth_window`` training samples (the last of each training segment),
and the chosen terms' weights are then re-estimated on the whole training split from the grown ones
(:func:`free_run_selection`). Along a long free run the sensitivities of a lightly damped model
build up (on Bouc-Wen's 32 768 training samples they grew by 1e8 after the 13th term, and every
candidate's sensitivity then lay numerically in the span of the current ones), the growth stops and
the weights stall in a poor minimum: grown on the whole record 1.08 % validation NMSE with 13 terms,
grown on the last 12 000 samples and re-estimated on all 0.078 % with 70 terms. A shorter run first
and the whole record after is a continuation in the horizon of the free run.

``growth_work`` bounds the growth by a count of its operations (:class:`GrowthWork`), not by the clock: the
refinement of m terms costs about m^2 per sample and Jacobian, and where the free run turns stiff its
Levenberg-Marquardt solves take up to ``max_nfev`` evaluations each (a generated Hammerstein system, 3200
samples: 0.1 s per step up to 75 terms, 2 to 12 s per step from 85 on, 564 s for 237 terms).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from dynmodel import regression
from dynmodel.data.dataset import compact_ranges, last_samples
from dynmodel.data.training import Series, TrainingData
from dynmodel.family import Progress

from . import kernels
from . import pool as pool_mod
from .embedding import OUTPUT, Embedding, factor_lists
from .estimation import FreeRunProblem, Scored, diverges, make_structure, output_error, refine, split_error
from .onestep import fixed_weights
from .params import NarxFamilyParams

_ROWS = 4096  # sensitivity rows per chunk


@dataclass
class GrowthWork:
    """Operations of the growth per training sample (time row), counted, never timed: a Jacobian of m terms
    costs m (m + P + 1) per output row (its QR m^2, the forward sensitivities m P, the terms m; P the largest
    output lag), a free run m, a step's candidate screening C (m + P + 1) for a pool of C (the sensitivity
    columns and the Gram entries FOS reads). Measured at 6.3e-10 s per operation and sample on Bouc-Wen's
    growth (12 000 samples, 10 to 90 terms), 3.3e-10 on a Hammerstein system's (3200 samples, 7 to 237)."""

    outputs: int
    lag: int
    ops: float = 0.0

    def solved(self, m: int) -> Any:
        """The ``after_step`` callback of :func:`refine` that counts one solve of ``m`` weights."""

        def count(mix: float, w: np.ndarray, res: Any) -> None:
            jac = int(getattr(res, "njev", 0) or 0)
            runs = int(getattr(res, "nfev", 0) or 0)
            self.ops += self.outputs * (jac * m * (m + self.lag + 1) + runs * m)

        return count

    def screened(self, pool: int, m: int) -> None:
        self.ops += self.outputs * pool * (m + self.lag + 1)


@dataclass
class Candidates:
    exponents: np.ndarray  # (C, n_reg)
    output: np.ndarray  # (C,)


def _sensitivity_gram(
    emb: Embedding, st, data: TrainingData, scored: Scored, w: np.ndarray, cand: Candidates, first: int, m: int
) -> tuple[np.ndarray, np.ndarray, float]:
    """The parts of the Gram matrix FOS reads, the correlations with the scaled residual, and the
    scaled target energy y'y of the candidates' free-run sensitivity columns, over the scored
    training rows at or after ``first``.

    Candidates 0 .. m-1 are the current terms, forced into the selection; choosing one more term
    then reads only the diagonal and the first m columns of the Gram matrix (A.2.2: step m needs
    <g_i|g_i> and <g_i|g_{i_k}> of the selected terms), so only those are computed (N C (m + 1)
    products instead of N C^2 / 2); the other entries are 0."""
    src, ch, lag = emb.arrays()
    fed = src == OUTPUT
    ptr, reg, pw = factor_lists(cand.exponents)
    n_out = st.n_out
    scale = 1.0 / np.sqrt(scored.n * scored.var)
    C = cand.exponents.shape[0]
    cols = np.zeros((C, m))
    diag = np.zeros(C)
    c = np.zeros(C)
    yy = 0.0
    P = max(1, int(lag[fed].max()) if fed.any() else 1)
    finite = np.isfinite(st.clip_lo) | np.isfinite(st.clip_hi)
    run = st.without_settling()
    for s, rows in enumerate(scored.rows):
        if not rows.size:
            continue
        ser = data.series[s]
        u, y = ser.u[: scored.stop[s]], ser.y[: scored.stop[s]]
        if settle := st.settle:  # the pre-roll's sensitivities carry into the run: run it here, unscored
            u, y = st.settled(u, y)
            rows = rows + settle
        stop = len(u)
        yhat, _ = run.run(u, y, w)
        live = np.ones(yhat.shape, dtype=np.bool_)
        if finite.any():
            live = ~((yhat == st.clip_lo) | (yhat == st.clip_hi))
        X = emb.matrix(u, yhat)
        D = kernels.model_gradient(X, st.ptr, st.reg, st.pw, st.out, w, n_out, fed)
        use = np.zeros(stop, dtype=np.bool_)
        use[rows[rows >= first + settle]] = True
        resid = (y - yhat) * scale
        prev = np.zeros((P, n_out, C))
        for t0 in range(0, stop, _ROWS):
            t1 = min(stop, t0 + _ROWS)
            S = kernels.candidate_sensitivities(
                X, D, ch, lag, fed, live, ptr, reg, pw, cand.output, st.start, t0, t1, prev
            )
            keep = use[t0:t1]
            if keep.any():
                A = np.ascontiguousarray((S[keep] * scale[None, :, None]).reshape(-1, C))
                cols += A.T @ A[:, :m]
                diag += np.einsum("ij,ij->j", A, A)
                r = resid[t0:t1][keep].ravel()
                c += A.T @ r
                yy += float(np.sum((y[t0:t1][keep] * scale) ** 2))
            tail = np.concatenate([prev, S])[-P:]
            prev = np.ascontiguousarray(tail)
    G = np.zeros((C, C))
    G[:, :m] = cols
    G[:m, :] = cols.T
    G[np.arange(C), np.arange(C)] = diag
    return G, c, yy


def training_window(data: TrainingData, samples: int) -> TrainingData:
    """``data`` with its training split cut to at most ``samples`` samples: the last ones of each training
    segment, in proportion to the segment's length; validation segments kept whole; every recording
    starts at its first kept sample (the free run starts there, as it does at a recording's start)."""
    train = data.segments.get("train", [])
    kept = last_samples(train, samples)
    if kept == train:
        return data
    cuts, segments = compact_ranges({"train": kept, "validation": list(data.segments.get("validation", []))})
    series = [Series(data.series[s].u[a:b], data.series[s].y[a:b]) for s, a, b in cuts]
    return dataclasses.replace(data, series=series, segments=segments)


def _linear_start(
    emb: Embedding,
    pool: np.ndarray,
    data: TrainingData,
    n_out: int,
    start: int,
    clip: tuple[np.ndarray, np.ndarray],
    band: tuple[np.ndarray, np.ndarray],
    p: NarxFamilyParams,
    limit: int,
    val: Scored | None,
    settle: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The model the growth starts from: the constant and the linear terms (an ARX model), chosen
    per output by FOS on the one-step error with as many terms as validate best in free run, with
    least-squares weights.

    Growing from the constant alone fails: the free run of a constant model is constant, so a fed-back
    output term's sensitivity is a multiple of the constant's (it cannot be chosen, or enters with
    a weight the refinement cannot move), and an input term alone is a static map that a dynamic
    system's validation error rejects, so the growth stops with the constant (Cascaded Tanks, EMPS:
    an integrator is never reached from zero weights). The linear model needs no such luck: one-step
    least squares finds its dynamics directly."""
    mats = pool_mod.regressor_matrices(data, emb)
    train = pool_mod.patterns(data, mats, "train", pool_mod.first_sample(emb, p.start))
    degree = pool.sum(axis=1)
    linear = np.flatnonzero(degree <= 1 if p.constant else degree == 1)
    E = pool[linear]
    G, C = pool_mod.gram(train.X, train.Y, E)
    forced = (0,) if p.constant else ()
    rows, outs = [], []
    for k in range(n_out):
        y = train.Y[:, k]
        score = None
        if val is not None:

            def score(order: list[int], coef: np.ndarray, k: int = k) -> float:
                st = make_structure(emb, E[order], np.full(len(order), k, dtype=np.int64), n_out, start, clip, settle)
                return output_error(st, data, val, coef, band, k)

        path = regression.fos_select(
            G,
            C[:, k],
            float(y @ y),
            forced=forced,
            max_terms=min(limit, len(linear)),
            validation=score,
            patience=len(linear),
        )
        kept = path.order[: max(path.best, 1)]
        rows.append(E[kept])
        outs += [k] * len(kept)
    exps = np.vstack(rows)
    outs_arr = np.array(outs, dtype=np.int64)
    return exps, outs_arr, fixed_weights(train, exps, outs_arr, n_out)


def free_run_selection(
    emb: Embedding,
    pool: np.ndarray,
    data: TrainingData,
    n_out: int,
    start: int,
    clip: tuple[np.ndarray, np.ndarray],
    band: tuple[np.ndarray, np.ndarray],
    params: NarxFamilyParams,
    progress: Progress,
    settle: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
    """Grow the model term by term on the linearised free-running error (module docstring), on at most
    ``growth_window`` training samples, then re-estimate the weights on the whole training split from the
    grown ones; those are kept when they validate no worse (without validation: always, since the
    Levenberg-Marquardt steps never raise the training error)."""
    p = params
    whole = data
    if p.growth_window is not None:
        data = training_window(data, p.growth_window)
    r = p.refinement
    scored = Scored.of(data, "train", start)
    val = Scored.of(data, "validation", start) if data.has("validation") else None
    use_val = val is not None and val.n > 0 and p.patience is not None
    if not use_val and p.max_terms is None and p.threshold is None:
        raise ValueError(
            "selection: free_run needs a stopping rule: a validation split (used with patience), max_terms or threshold"
        )
    limit = p.max_terms if p.max_terms is not None else pool.shape[0]
    finite_clip = (np.maximum(clip[0], band[0]), np.minimum(clip[1], band[1]))
    src, _, lags = emb.arrays()
    work = GrowthWork(n_out, int(lags[src == OUTPUT].max()) if (src == OUTPUT).any() else 0)
    allowed = None if p.growth_work is None else p.growth_work * 1e6
    stopped = ""
    if p.free_run_start == "linear":
        exps, outs, w = _linear_start(
            emb, pool, data, n_out, start, clip, band, p, limit, val if use_val else None, settle
        )
        st0 = make_structure(emb, exps, outs, n_out, start, clip, settle)
        unstable = diverges(st0, data, scored, w, band)
        mixes = [1.0 - i / r.ramp for i in range(1, r.ramp + 1)] if unstable else [0.0]
        w = refine(
            FreeRunProblem(st0, data, scored, finite_clip), w, mixes, r.solver, r.max_nfev, r.tol, work.solved(len(w))
        )
        progress("select", None, f"{len(w)} terms: the linear model (ARX) re-estimated on the free run")
    elif p.constant:
        const = ~pool.any(axis=1)
        exps = np.repeat(pool[const][:1], n_out, axis=0)
        outs = np.arange(n_out, dtype=np.int64)
        w = np.array(
            [
                np.mean(np.concatenate([data.series[s].y[rr, k] for s, rr in enumerate(scored.rows)]))
                for k in range(n_out)
            ]
        )
    else:
        exps = np.zeros((0, emb.size), dtype=np.int64)
        outs = np.zeros(0, dtype=np.int64)
        w = np.zeros(0)
    first = start + emb.max_lag  # scored rows whose every regressor comes from the free run itself
    history: list[dict[str, Any]] = [
        {
            "added": " + ".join(emb.label_of(e) for e in exps) or None,
            "terms": int(len(w)),
            "start": p.free_run_start,
            "work": work.ops / 1e6,
        }
    ]
    best = None
    best_err, since_best = np.inf, 0
    while True:
        st = make_structure(emb, exps, outs, n_out, start, clip, settle)
        if use_val and val is not None and p.patience is not None:  # (use_val implies both)
            err = split_error(st, data, val, w, band)
            history[-1]["validation_nmse"] = None if not np.isfinite(err) else 100 * err
            if best is None or err < best_err * (1 - 1e-12):  # the start is kept even when it diverges there
                best, best_err, since_best = (exps.copy(), outs.copy(), w.copy()), err, 0
            else:
                since_best += 1
                if since_best >= p.patience:
                    stopped = f"no lower validation error for {p.patience} terms (patience)"
                    break
        else:
            best = (exps.copy(), outs.copy(), w.copy())
        if allowed is not None and work.ops >= allowed:
            stopped = f"growth_work reached ({work.ops / 1e6:.3g} million operations per sample)"
            progress("select", None, f"{len(w)} terms: the growth's work limit is reached")
            break
        counts = np.bincount(outs, minlength=n_out)
        taken = {(int(o), e.tobytes()) for e, o in zip(exps, outs)}
        new = [(e, k) for k in range(n_out) if counts[k] < limit for e in pool if (k, e.tobytes()) not in taken]
        if not new:
            stopped = "max_terms reached" if p.max_terms is not None else "every term of the pool taken"
            break
        cand = Candidates(
            np.vstack([exps] + [e[None] for e, _ in new]),
            np.concatenate([outs, np.array([k for _, k in new], dtype=np.int64)]),
        )
        m = len(w)
        G, c, yy = _sensitivity_gram(emb, st, data, scored, w, cand, first, m)
        work.screened(cand.exponents.shape[0], m)
        path = regression.fos_select(
            G, c, yy, forced=tuple(range(m)), max_terms=m + 1, threshold=p.threshold, ties=1e-9
        )
        added = [int(i) for i in path.order if i >= m]  # the current terms are forced (some may be skipped)
        if not added:
            stopped = "no candidate reduces the free-running error" if p.threshold is None else "threshold"
            break
        j = added[0]
        order = np.argsort(np.append(outs, cand.output[j]), kind="stable")
        exps = np.vstack([exps, cand.exponents[j][None]])[order]
        outs = np.append(outs, cand.output[j])[order]
        w = np.append(w, 0.0)[order]
        st = make_structure(emb, exps, outs, n_out, start, clip, settle)
        w = refine(
            FreeRunProblem(st, data, scored, finite_clip), w, [0.0], r.solver, r.max_nfev, r.tol, work.solved(len(w))
        )
        label = emb.label_of(cand.exponents[j])
        history.append(
            {
                "added": label if n_out == 1 else f"{label} (output {int(cand.output[j]) + 1})",
                "error_reduction": float(path.error_reduction[list(path.order).index(j)] / max(yy, 1e-300)),
                "terms": int(len(w)),
                "work": work.ops / 1e6,  # counted so far, million operations per sample (growth_work)
            }
        )
        progress("select", None, f"{len(w)} terms: + {label}")
    assert best is not None
    exps, outs, w = best
    info: dict[str, Any] = {
        "method": "free_run",
        "pool": int(pool.shape[0]),
        "terms": [int(np.sum(outs == k)) for k in range(n_out)],
        "path": history,
        "stopped": stopped,
        "work": work.ops / 1e6,
    }
    if data is not whole:
        st = make_structure(emb, exps, outs, n_out, start, clip, settle)
        w, info["window"] = _refit_on_whole(st, whole, w, start, finite_clip, band, p, progress)
    return exps, outs, w, info


def _refit_on_whole(
    st, data: TrainingData, w: np.ndarray, start: int, clip, band, p: NarxFamilyParams, progress: Progress
) -> tuple[np.ndarray, dict[str, Any]]:
    """The grown weights ``w`` re-estimated on the whole training split of ``data``; the refitted ones are
    returned when they validate no worse (without validation: always, since the Levenberg-Marquardt steps
    never raise the training error), with a record of the choice."""
    r = p.refinement
    progress("select", None, f"{len(w)} terms: weights re-estimated on the whole training split")
    w_all = refine(
        FreeRunProblem(st, data, Scored.of(data, "train", start), clip), w, [0.0], r.solver, r.max_nfev, r.tol
    )
    record: dict[str, Any] = {"samples": p.growth_window, "weights": "whole"}
    val = Scored.of(data, "validation", start) if data.has("validation") else None
    if val is not None and val.n:
        grown, refitted = split_error(st, data, val, w, band), split_error(st, data, val, w_all, band)
        record["validation_nmse_grown"] = None if not np.isfinite(grown) else 100 * grown
        record["validation_nmse_whole"] = None if not np.isfinite(refitted) else 100 * refitted
        if not refitted <= grown:
            record["weights"] = "window"
            return w, record
    return w_all, record
