"""The `narx` family: polynomial NARX models (thesis 3.1, 3.2, A.2.2, 6.3.2).

Embedding (3.1.1): regressors are inputs at lags >= 0 and past outputs at lags >= 1. Pool: every
monomial of the regressors up to ``degree`` plus a constant (eq. 3.10). Structure: Fast
Orthogonal Search on the pool's Gram matrix (A.2.2), stopped by ``max_terms``, ``threshold`` or
the first rise of the one-step validation error (A.3); one polynomial per output, each offered
every output's past. Weights: least squares, FOS's recursion (A.14 / A.15) or ridge (6.3.2).
``cost: mse_inf`` re-estimates the weights on the free-running error (eq. 3.15). The free run
can be bounded (eq. 6.25) and reports the sample where it diverges.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable
from typing import Any, Literal

import numpy as np

from dynmodel.data.dataset import continued_range, last_samples
from dynmodel.data.delay import READ_ON, dead_times
from dynmodel.data.training import TrainingData
from dynmodel.family import Family, Progress, Simulation, constructor_arguments, no_progress

from . import orders
from . import pool as pool_mod
from .embedding import (
    DEFAULT_MAX_LAG,
    Embedding,
    Regressor,
    build_embedding,
    default_lag_table,
    exponents_of,
    parse_term,
    term_label,
)
from .estimation import (
    FreeRunProblem,
    Scored,
    Structure,
    diverges,
    make_structure,
    one_output,
    output_error,
    refine,
    segment_view,
    split_error,
)
from .linear_start import steiglitz_mcbride
from .onestep import fixed_weights, fos_structure, make_pool, ridge_candidates
from .params import SETTLE_SAMPLES, FreeRunRefinement, LagRange, NarxFamilyParams
from .selection import free_run_selection

#: finalists of the lag and degree search are re-estimated on the free run (cost mse_inf) only when their
#: least-squares free-run validation error is within this factor of the best one (the largest gain of the
#: re-estimation measured: 8.7x, GMS friction; Silverbox's linear finalists are 860x behind)
_REFINE_WITHIN = 20.0
#: the stress test of the lag and degree search: inputs stretched about their mean by this factor; a finalist
#: that diverges there is kept only if its validation error is lower than the best bounded one's by _CLEARLY_BETTER
_STRESS = 1.5
_CLEARLY_BETTER = 3.0
#: other (lags, degree) pairs of the search kept in line, fitted when every finalist fails its free run
_RESERVES = 4


#: parameters that choose the structure, left out of :meth:`Narx.frozen_config` (the terms are given instead)
_CHOOSING = (
    "lags",
    "degree",
    "terms",
    "initial_weights",
    "selection",
    "max_terms",
    "threshold",
    "stop_on",
    "patience",
    "growth_window",
    "growth_work",
)


class Narx(Family):
    name = "narx"
    description = (
        "polynomial NARX model: FOS structure selection, free-running estimation (thesis 3.1, 3.2, A.2.2, 6.3.2)"
    )
    Params = NarxFamilyParams
    stochastic = False  # FOS, least squares and the free-run refinement are deterministic
    default_cost = "mse_inf"  # the model is used in free run: estimate it there (thesis 3.2, 6.3.2)
    stability_hint = (
        "use cost: mse_inf (free-running estimation), bounds: 0.1 (clip the output, eq. 6.25), ridge: auto, "
        "or a lower degree"
    )
    warmup_hint = (
        "use lags of at most {window} samples, or initial: settled (the free run starts from rest at its first "
        "input) or zeros (from the training mean)"
    )

    params: NarxFamilyParams

    def __init__(
        self,
        *,
        lags: dict[str, list[int | LagRange | dict[str, int]]] | None = None,
        degree: int | None = None,
        constant: bool = True,
        input_terms: Literal["any", "linear"] = "any",
        terms: list[str] | dict[str, list[str]] | None = None,
        initial_weights: list[float] | dict[str, list[float]] | None = None,
        selection: Literal["one_step", "free_run"] = "one_step",
        free_run_start: Literal["linear", "constant"] = "linear",
        growth_window: int | None = None,
        growth_work: float | None = None,
        max_terms: int | None = None,
        threshold: float | None = None,
        stop_on: Literal["free_run", "one_step"] = "free_run",
        patience: int | None = 20,
        drop_unstable: bool = True,
        weights: Literal["lstsq", "recursion"] = "lstsq",
        ridge: float | Literal["auto"] | None = None,
        bounds: float | dict[str, tuple[float | None, float | None]] | None = 0.5,
        clip_while_choosing: bool = False,
        start: Literal["drop", "zeros"] = "drop",
        initial: Literal["measured", "zeros", "settled"] = "measured",
        max_pool: int = 3000,
        refinement: FreeRunRefinement | dict[str, Any] | None = None,
    ) -> None:
        """Parameters as in ``NarxFamilyParams`` (the spec's ``model.params``); see the class help."""
        super().__init__(**constructor_arguments(locals()))

    # ------------------------------------------------------------------ structure
    @property
    def warmup(self) -> int:
        """``initial: measured``: the first L samples (L = the largest lag) are measured (before
        ``fit``: the largest lag the parameters name)."""
        if self.params.initial != "measured":
            return 0
        emb = getattr(self, "embedding_", None)
        return emb.max_lag if emb is not None else self._planned_max_lag()

    def _planned_max_lag(self) -> int:
        p = self.params
        table = p.lag_table()
        lags = [lag for values in table.values() for lag in values] if table is not None else []
        if table is None and p.terms is None:
            lags.append(DEFAULT_MAX_LAG)  # lags chosen on the data, at most this long
        if p.terms is not None:
            terms = p.terms if isinstance(p.terms, list) else [t for ts in p.terms.values() for t in ts]
            for text in terms:
                try:
                    lags += [lag for _, lag, _ in parse_term(text)]
                except ValueError:  # reported by fit, with its context
                    pass
        return max(lags, default=0)

    def _structure(self) -> Structure:
        return make_structure(
            self.embedding_,
            self.exponents_,
            self.term_output_,
            self.n_outputs_,
            self.warmup,
            (self.clip_lo_, self.clip_hi_),
            self._settle,
        )

    @property
    def _settle(self) -> int:
        """Pre-roll samples of a free run (``initial: settled``), 0 otherwise."""
        return SETTLE_SAMPLES if self.params.initial == "settled" else 0

    def _check_structure(self) -> Structure:
        """The model without its output clip, for the checks that choose it (see :meth:`_check_band`);
        with ``clip_while_choosing`` the clipped model itself."""
        st = self._structure()
        if self.params.clip_while_choosing:
            return st
        st.clip_lo = np.full(self.n_outputs_, -np.inf)
        st.clip_hi = np.full(self.n_outputs_, np.inf)
        return st

    @property
    def _unclipped(self) -> tuple[np.ndarray, np.ndarray]:
        return np.full(self.n_outputs_, -np.inf), np.full(self.n_outputs_, np.inf)

    def _check_band(self) -> tuple[np.ndarray, np.ndarray]:
        """The band a free run must stay in while the model is chosen (sizes, lags, weights). Without
        ``bounds``: the divergence band. With them: the output clip, widened where it is tighter than the
        measured outputs' range (training and validation, :meth:`_set_clip`) +- half the training
        range's width, within the divergence band. The clip is for inputs the training data never showed; a
        model that needs it on its own training or validation inputs is broken there, and clipped it would pass
        every divergence check unnoticed. With ``clip_while_choosing`` the clip is part of the model: only the
        divergence band."""
        lo, hi = self._bounds
        if self.params.clip_while_choosing or not (
            np.isfinite(self.clip_lo_).any() or np.isfinite(self.clip_hi_).any()
        ):
            return lo, hi
        plo, phi = self._plausible
        return np.maximum(lo, np.minimum(self.clip_lo_, plo)), np.minimum(hi, np.maximum(self.clip_hi_, phi))

    @property
    def terms_(self) -> list[list[str]]:
        """Per output: the selected terms as text."""
        labels = [r.label for r in self.embedding_.regressors]
        return [
            [term_label(e, labels) for e in self.exponents_[self.term_output_ == k]] for k in range(self.n_outputs_)
        ]

    # ------------------------------------------------------------------ fitting
    def fit(
        self,
        data: TrainingData,
        cost: str = "mse1",
        rng: np.random.Generator | None = None,
        progress: Progress = no_progress,
    ) -> Narx:
        p = self.params
        self.n_inputs_, self.n_outputs_ = data.n_inputs, data.n_outputs
        self.output_names_ = list(data.output_names)
        self.ridge_: dict[str, Any] | None = None
        fixed = self._fixed_terms(data)
        extra = [(name, lag) for terms in (fixed or {}).values() for t in terms for name, lag, _ in parse_term(t)]
        self._check_names(extra, data)
        self.embedding_ = build_embedding(
            p.lag_table() if (p.lags is not None or not fixed) else {},
            data.input_names,
            data.output_names,
            extra,
            p.max_degree,
            p.constant,
            p.input_terms == "linear",
        )
        emb = self.embedding_
        train, val = self._patterns_of(data, emb)
        if train.n <= emb.size:
            raise ValueError(
                f"only {train.n} training patterns with known regressors (largest lag {emb.max_lag}); "
                "provide more training data or use shorter lags"
            )
        self._bounds = data.output_bounds()
        self._set_clip(data, train.Y)

        self.refinement_: list[dict[str, Any]] = []
        if p.selection == "free_run" and fixed is None:
            if cost != "mse_inf":
                raise ValueError(
                    "selection: free_run estimates the weights on the free-running error; use it with "
                    "cost: mse_inf (or selection: one_step)"
                )
            if p.ridge is not None:
                raise ValueError(
                    "ridge applies to least-squares weights; selection: free_run estimates them on the "
                    "free-running error, so leave ridge out (or use selection: one_step)"
                )
            self._check_initial(data)
            exps, outs, weights, self.selection_ = free_run_selection(
                emb,
                make_pool(emb, p),
                data,
                self.n_outputs_,
                self.warmup,
                (self.clip_lo_, self.clip_hi_) if p.clip_while_choosing else self._unclipped,
                self._check_band(),
                p,
                progress,
                self._settle,
            )
            self.exponents_, self.term_output_, self.weights_ = exps, outs, weights
            self._warn_if_input_free()
            return self
        if fixed is not None:
            exps, outs = self._fixed_structure(fixed, data.output_names)
            weights = fixed_weights(train, exps, outs, self.n_outputs_)
            self.selection_ = {"method": "fixed", "terms": [int(np.sum(outs == k)) for k in range(self.n_outputs_)]}
        elif (p.lags is None or p.degree is None) and val is not None and self._free_run_error(data) is not None:
            return self._fit_finalists(data, *self._search_orders(data, train, val, progress), cost, progress)
        else:
            exps, outs, weights, self.selection_ = fos_structure(
                make_pool(emb, p),
                train,
                val,
                p,
                self.output_names_,
                self._stability_check(data),
                progress,
                self._free_run_error(data),
            )
        self.exponents_, self.term_output_ = exps, outs
        self.weights_ = weights
        if p.ridge is not None:
            self._ridge(data, train, progress)

        start = self._initial_weights(data.output_names, cost)  # given only with terms (the params check it)
        if cost == "mse_inf":
            self._refine(data, progress, initial=start)
        self._warn_if_input_free()
        return self

    def _search_orders(
        self, data: TrainingData, train: pool_mod.Patterns, val: pool_mod.Patterns, progress: Progress
    ) -> tuple[list[dict[str, Any]], list[Callable[[], dict[str, Any]]]]:
        """``lags: null`` / ``degree: null``: FOS on every sub-pool (lags <= L, degree <= d) of the
        largest pool's Gram matrix, each stopped by its free-run validation error (see :mod:`.orders`).
        With ``lags: null``, where an input acts only after a dead time (:meth:`_dead_times`), the sub-pools of
        the default table with that input's lags starting there (:meth:`_after_dead_times`) compete too: lags
        0 .. 6 never reach an input that acts 25 samples later.
        Returns the finalists (per degree the lags whose least-squares model validates best, each
        written on its own embedding, best first) and the reserves: up to ``_RESERVES`` other (lags,
        degree) pairs in the order of their least-squares validation error, each written when called
        (fitted only when every finalist fails, see :meth:`_fit_finalists`)."""
        p = self.params
        tables: list[tuple[Embedding, pool_mod.Patterns, pool_mod.Patterns, dict[str, int]]] = [
            (self.embedding_, train, val, {})
        ]
        delays = self._dead_times(data) if p.lags is None else {}
        if delays:
            shifted = self._after_dead_times(data, delays)
            if shifted is not None:
                shifted_train, shifted_val = self._patterns_of(data, shifted)
                if shifted_val is not None and shifted_train.n > shifted.size:
                    tables.append((shifted, shifted_train, shifted_val, delays))
        degrees = [p.degree] if p.degree is not None else list(range(1, p.max_degree + 1))
        tried: list[dict[str, Any]] = []
        found_all: list[tuple[float, orders.Candidate, tuple, Embedding, dict[str, int]]] = []
        for emb, emb_train, emb_val, dead in tables:
            self.embedding_ = emb  # the closures below run its polynomials, from its tune-in
            E = make_pool(emb, p)
            progress("pool", None, f"Gram matrix of {E.shape[0]} monomials on {emb_train.n} patterns")
            G, C = pool_mod.gram(emb_train.X, emb_train.Y, E)
            lag_values: list[int | None] = (
                list(range(1, int(orders.memory_lags(emb).max()) + 1)) if p.lags is None else [None]
            )
            stability, error = self._stability_check(data), self._free_run_error(data)
            after = f", inputs from their dead times {dead}" if dead else ""
            for cand in orders.candidates(emb, E, lag_values, degrees):
                where = f"lags {cand.lag if cand.lag is not None else 'as given'}{after}, degree {cand.degree}"

                def step(stage: str, fraction: float | None, message: str, where: str = where) -> None:
                    progress("orders", None, f"{where}: {message}")

                sub = cand.rows
                found = fos_structure(
                    E[sub],
                    emb_train,
                    emb_val,
                    p,
                    self.output_names_,
                    stability,
                    step,
                    error,
                    (G[np.ix_(sub, sub)], C[sub]),
                )
                err = orders.score(found[3])
                tried.append(
                    {
                        "lags": cand.lag,
                        **({"dead_times": dict(dead)} if dead else {}),
                        "degree": cand.degree,
                        "terms": found[3]["terms"],
                        "validation_free_run_nmse": None if not np.isfinite(err) else err,
                    }
                )
                found_all.append((err, cand, found, emb, dead))
        ranked = sorted(found_all, key=lambda f: f[0])  # stable: ties keep the smaller pool first
        best: dict[int, tuple] = {}
        for entry in ranked:
            best.setdefault(entry[1].degree, entry)
        heads = sorted(best.values(), key=lambda b: b[0])
        heads = [h for i, h in enumerate(heads) if i == 0 or np.isfinite(h[0])]
        reserves = [r for r in ranked if np.isfinite(r[0]) and all(r is not h for h in heads)][:_RESERVES]

        def written(entry: tuple) -> dict[str, Any]:
            err, cand, (exps, outs, weights, info), emb, dead = entry
            info = {**info, "lags": cand.lag, **({"dead_times": dict(dead)} if dead else {}), "degree": cand.degree}
            info["search"] = tried
            small = emb
            if cand.lag is not None and cand.lag < int(orders.memory_lags(emb).max()):
                small = build_embedding(orders.lag_tables(emb, cand.lag), data.input_names, data.output_names)
                exps = orders.remap(exps, emb, small)
                if p.weights == "lstsq":  # the smaller embedding drops fewer patterns at recording starts
                    weights = fixed_weights(self._patterns(data, small, "train"), exps, outs, self.n_outputs_)
            return {
                "embedding": small,
                "exponents": exps,
                "term_output": outs,
                "weights": weights,
                "selection": info,
                "least_squares_error": err,
            }

        return [written(h) for h in heads], [functools.partial(written, r) for r in reserves]

    def _dead_times(self, data: TrainingData) -> dict[str, int]:
        """The inputs that act on an output only after a dead time of at least ``MIN_DELAY`` samples, read on the
        last ``READ_ON`` training samples (:func:`dynmodel.data.delay.dead_times`)."""
        if not self.n_inputs_:
            return {}
        rows = last_samples(data.segments.get("train", []), READ_ON)
        u = [data.series[i].u[a:b] for i, a, b in rows]
        y = [data.series[i].y[a:b] for i, a, b in rows]
        return dead_times(u, y, data.input_names) if rows else {}

    def _after_dead_times(self, data: TrainingData, delays: dict[str, int]) -> Embedding | None:
        """The default table with each input's lags starting at its dead time (inputs d .. d + L, outputs
        1 .. L), or None when its tune-in (d + L measured outputs) is longer than a protocol allows."""
        p = self.params
        table = default_lag_table(
            data.input_names, data.output_names, p.max_degree, p.constant, p.input_terms == "linear"
        )
        for name, d in delays.items():
            table[name] = [lag + d for lag in table[name]]
        emb = build_embedding(
            table, data.input_names, data.output_names, (), p.max_degree, p.constant, p.input_terms == "linear"
        )
        limit = data.warmup_limit
        if p.initial == "measured" and limit is not None and emb.max_lag > limit:
            return None
        return emb

    def _patterns_of(self, data: TrainingData, emb: Embedding) -> tuple[pool_mod.Patterns, pool_mod.Patterns | None]:
        """The training and validation patterns of ``emb`` (None: no validation pattern), from one regressor
        matrix."""
        mats = pool_mod.regressor_matrices(data, emb)
        first = pool_mod.first_sample(emb, self.params.start)
        train = pool_mod.patterns(data, mats, "train", first)
        val = pool_mod.patterns(data, mats, "validation", first) if data.has("validation") else None
        return train, (val if val is not None and val.n else None)

    def _patterns(self, data: TrainingData, emb: Embedding, split: str) -> pool_mod.Patterns:
        first = pool_mod.first_sample(emb, self.params.start)
        return pool_mod.patterns(data, pool_mod.regressor_matrices(data, emb), split, first)

    def _fit_finalists(
        self,
        data: TrainingData,
        heads: list[dict[str, Any]],
        reserves: list[Callable[[], dict[str, Any]]],
        cost: str,
        progress: Progress,
    ):
        """Ridge and ``mse_inf`` for each finalist of the lag and degree search; the one whose free run
        validates best is kept (its least-squares ranking need not survive the free-running estimation:
        a polynomial that diverges with least-squares weights can be the best one after it).

        Only finalists within ``_REFINE_WITHIN`` of the best least-squares error are fitted. When every one
        of them still leaves the band (or needs its output clip) on the training or validation data after
        the fit, the others (the skipped finalists and the reserves) are fitted in the order of their
        least-squares error until one does not: the least-squares search scores a model clipped as it runs,
        and the free-running estimation does not always repair a model that needs its clip (a generated
        Wiener system: the 113-term finalist, 0.033 % validation NMSE clipped, ended at 35 000 %; the
        degree-3 model on lags up to 5, next in line, validates at 0.022 %)."""
        fitted: list[tuple[bool, float, dict[str, Any]]] = []
        lowest = heads[0]["least_squares_error"]
        waiting: list[dict[str, Any]] = []
        for i, f in enumerate(heads):
            if i > 0 and cost == "mse_inf" and not f["least_squares_error"] <= _REFINE_WITHIN * lowest:
                f["selection"]["validation_nmse"] = None  # free-running estimation does not close such a gap
                waiting.append(f)
                continue
            fitted.append(self._fit_finalist(data, f, cost, progress, f"finalist {i + 1}/{len(heads)}"))
        skipped = {id(f) for f in waiting}
        tried = [f for f in heads if id(f) not in skipped]
        fallback: set[int] = set()
        if not any(f[1] < 1e6 for f in fitted):
            waiting += [write() for write in reserves]
            waiting.sort(key=lambda f: f["least_squares_error"])
            for j, f in enumerate(waiting):
                fitted.append(self._fit_finalist(data, f, cost, progress, f"next in line {j + 1}/{len(waiting)}"))
                tried.append(f)
                fallback.add(id(f))
                if fitted[-1][1] < 1e6:
                    break
        best = min(fitted, key=lambda f: f[1])
        safe = [f for f in fitted if f[0]]
        if not best[0] and safe:
            # prefer the best bounded finalist unless the fragile one validates clearly better (a validation split
            # lies where the training data lie and cannot see what the fragile one does beyond them)
            best_safe = min(safe, key=lambda f: f[1])
            if not best[1] * _CLEARLY_BETTER < best_safe[1]:
                best = best_safe
        vars(self).update(best[2])
        self.selection_["finalists"] = [
            {
                "lags": f["selection"]["lags"],
                "degree": f["selection"]["degree"],
                "terms": f["selection"]["terms"],
                "validation_nmse": f["selection"].get("validation_nmse"),
                "larger_inputs": f["selection"].get("larger_inputs"),
                **({"next_in_line": True} if id(f) in fallback else {}),
            }
            for f in heads + [f for f in tried if id(f) in fallback and id(f) not in skipped]
        ]
        if cost == "mse_inf":
            self._warn_if_diverging(data)
        self._warn_if_input_free()
        return self

    def _fit_finalist(
        self, data: TrainingData, f: dict[str, Any], cost: str, progress: Progress, label: str
    ) -> tuple[bool, float, dict[str, Any]]:
        """Fit one finalist (ridge, ``mse_inf``) and score it: (bounded under larger inputs, validation error or
        1e6 + its clipped error when it needs its clip there, the fitted state)."""
        self.embedding_ = f["embedding"]
        self.exponents_, self.term_output_, self.weights_ = f["exponents"], f["term_output"], f["weights"]
        self.selection_ = f["selection"]
        self.refinement_ = []
        self.ridge_ = None
        if self.params.ridge is not None:
            self._ridge(data, self._patterns(data, self.embedding_, "train"), progress)
        if cost == "mse_inf":
            progress("orders", None, f"{label}: lags {self.selection_['lags']}, degree {self.selection_['degree']}")
            self._refine(data, progress, warn=False)
        st, scored = self._check_structure(), Scored.of(data, "validation", self.warmup)
        err = split_error(st, data, scored, self.weights_, self._check_band())
        if not np.isfinite(err):  # needs its clip on validation: ranked behind every finalist that does not
            err = 1e6 + split_error(self._structure(), data, scored, self.weights_, self._bounds)
        self.selection_["validation_nmse"] = None if not err < 1e6 else 100 * err
        robust = self._survives_larger_inputs(data)
        self.selection_["larger_inputs"] = "bounded" if robust else "diverges"
        return robust, err, dict(vars(self))

    def _survives_larger_inputs(self, data: TrainingData) -> bool:
        """Does the free run stay inside the divergence band when every training recording's input is
        stretched about its mean by ``_STRESS`` (50 % beyond the training inputs)? Validation data lie
        where the training data lie, so they cannot show that a polynomial with cubic feedback terms
        escapes to infinity on the first input a little larger than any it saw (narx-system, EMPS's
        pulses); a model that does is kept only when it validates clearly better than every bounded one."""
        st = self._check_structure()
        mean = np.mean(np.concatenate([ser.u for ser in data.series]), axis=0)
        for ser in data.series:
            u = np.ascontiguousarray(mean + _STRESS * (ser.u - mean))
            y = ser.y[: min(st.start, ser.n)]
            if st.start and not np.isfinite(y).all():
                continue
            if st.run(u, y, self.weights_, 0.0, self._bounds)[1] >= 0:
                return False
        return True

    def _warn_if_input_free(self) -> None:
        if self.n_inputs_ and not orders.uses_inputs(self.embedding_, self.exponents_):
            warnings.warn(
                "narx: no kept term depends on an input, so the free run ignores the input (an autonomous "
                "model); no input term validated better here; try longer lags, a higher degree, selection: "
                "free_run or another family",
                stacklevel=3,
            )

    def _check_names(self, extra: list[tuple[str, int]], data: TrainingData) -> None:
        known = set(data.input_names) | set(data.output_names)
        for name, _ in extra:
            if name not in known:
                raise ValueError(
                    f"terms: '{name}' is not a column of the data; the model inputs are "
                    f"{list(data.input_names)} and the outputs {list(data.output_names)}"
                )

    def _fixed_terms(self, data: TrainingData) -> dict[str, list[str]] | None:
        t = self.params.terms
        if t is None:
            return None
        if isinstance(t, list):
            return {name: list(t) for name in data.output_names}
        unknown = [k for k in t if k not in data.output_names]
        if unknown:
            raise ValueError(f"terms: '{unknown[0]}' is not an output; the outputs are {list(data.output_names)}")
        missing = [k for k in data.output_names if k not in t]
        if missing:
            raise ValueError(f"terms: no terms for output '{missing[0]}'; give a list for every output")
        return {k: list(v) for k, v in t.items()}

    def _fixed_structure(self, fixed: dict[str, list[str]], outputs: list[str]) -> tuple[np.ndarray, np.ndarray]:
        rows, outs = [], []
        for k, name in enumerate(outputs):
            if not fixed[name]:
                raise ValueError(f"terms: the list for output '{name}' is empty")
            E = exponents_of(fixed[name], self.embedding_)
            rows.append(E)
            outs += [k] * len(E)
        return np.vstack(rows), np.array(outs, dtype=np.int64)

    def _initial_weights(self, outputs: list[str], cost: str) -> np.ndarray | None:
        """``initial_weights`` in the order of the given terms' weights (output by output), None when not given."""
        w = self.params.initial_weights
        if w is None:
            return None
        if cost != "mse_inf":
            raise ValueError(
                f"initial_weights start the free-running estimation, and cost {cost} has none (least squares needs "
                "no start): use cost: mse_inf, or leave initial_weights out"
            )
        per = w if isinstance(w, dict) else {name: w for name in outputs}
        return np.concatenate([np.asarray(per[name], dtype=np.float64) for name in outputs])

    def _stability_check(self, data: TrainingData):
        """diverges(k, exponents, weights): does output k's polynomial, fed back its own prediction
        (the other outputs measured), leave the divergence band on the training or validation data?
        None when the free run cannot start (measured initial values inside the test split)."""
        try:
            self._check_initial(data)
        except ValueError:
            return None
        start = self.warmup
        splits = [Scored.of(data, s, start) for s in ("train", "validation") if data.has(s)]

        def check(k: int, exps: np.ndarray, w: np.ndarray) -> bool:
            # the model as it runs, clipped: a least-squares model that needs its clip here may be the one
            # the free-running estimation repairs (GMS friction: 6 % -> 0.7 % validation NMSE)
            st = self._output_structure(k, exps, start)
            mix, bounds = one_output(self.n_outputs_, k, self._bounds)
            return any(diverges(st, data, sc, w, bounds, mix) for sc in splits)

        return check

    def _output_structure(self, k: int, exps: np.ndarray, start: int) -> Structure:
        """Output ``k``'s polynomial with terms ``exps`` alone, clipped as the model runs."""
        outputs = np.full(len(exps), k, dtype=np.int64)
        clip = (self.clip_lo_, self.clip_hi_)
        return make_structure(self.embedding_, exps, outputs, self.n_outputs_, start, clip, self._settle)

    def _free_run_error(self, data: TrainingData):
        """error(k, exponents, weights): free-run NMSE of output k's polynomial (the other outputs fed
        back measured) on the validation split, inf when it leaves the divergence band; None without
        a validation split or when the free run cannot start."""
        if not data.has("validation"):
            return None
        try:
            self._check_initial(data)
        except ValueError:
            return None
        start = self.warmup
        view = segment_view(data, "validation", start)
        if not all(np.isfinite(ser.y[:start]).all() for ser in view.series):
            view = data  # the initial past would lie in the test split: run from the recordings' starts
        scored = Scored.of(view, "validation", start)
        if scored.n == 0:
            return None

        def error(k: int, exps: np.ndarray, w: np.ndarray) -> float:
            return output_error(self._output_structure(k, exps, start), view, scored, w, self._bounds, k)

        return error

    def _set_clip(self, data: TrainingData, Y: np.ndarray) -> None:
        """Output bounds [L, U] of eq. 6.25 in model space: the measured outputs' range (training, and
        validation where it continues a training recording: :func:`~dynmodel.data.dataset.continued_range`)
        widened by ``bounds`` x the training range's width, or the given values converted from the data's
        units; and the band of plausible outputs the checks read (:meth:`_check_band`), widened by half that
        width. A generated Wiener-Hammerstein system's middle fifth, held out for cross-validation, went down
        to -3.12 where the other four reach -1.15: against the training range alone every degree-3 model
        needed its clip there, and the default chose a linear one (9.7 % validation NMSE over 0.35 %)."""
        b = self.params.bounds
        lo, hi = Y.min(axis=0), Y.max(axis=0)
        width = hi - lo
        measured = continued_range(
            [ser.y for ser in data.series], data.segments.get("validation", []), data.segments.get("train", [])
        )
        if measured is not None:  # a validation output beyond the training range is measured, not diverging
            lo, hi = np.fmin(lo, measured[0]), np.fmax(hi, measured[1])
        self._plausible = (lo - 0.5 * width, hi + 0.5 * width)
        self.clip_lo_ = np.full(self.n_outputs_, -np.inf)
        self.clip_hi_ = np.full(self.n_outputs_, np.inf)
        if b is None:
            return
        if isinstance(b, dict):
            unknown = [k for k in b if k not in self.output_names_]
            if unknown:
                raise ValueError(f"bounds: '{unknown[0]}' is not an output; the outputs are {self.output_names_}")
            lo = np.array([-np.inf if b.get(n, (None, None))[0] is None else b[n][0] for n in self.output_names_])
            hi = np.array([np.inf if b.get(n, (None, None))[1] is None else b[n][1] for n in self.output_names_])
            self.clip_lo_, self.clip_hi_ = data.to_model_outputs(lo), data.to_model_outputs(hi)
            return
        self.clip_lo_ = lo - b * width
        self.clip_hi_ = hi + b * width

    # ------------------------------------------------------------------ ridge (6.3.2)
    def _ridge(self, data: TrainingData, train: pool_mod.Patterns, progress: Progress) -> None:
        """Ridge weights for the selected terms. ``auto``: the factor whose free run has the lowest
        validation error (thesis 6.3.2: ridge as a stabilizer, its factor tuned on validation)."""
        ridge = self.params.ridge
        assert ridge is not None  # called only with a ridge
        vectors, factors = ridge_candidates(train, self.exponents_, self.term_output_, self.weights_, ridge)
        if len(vectors) == 1:
            self.weights_, self.ridge_ = vectors[0], {"alpha": factors[0]}
            return
        if not data.has("validation"):
            raise ValueError(
                "ridge: auto chooses the factor on the validation split, and there is none; "
                "give a number or add a validation split"
            )
        self._check_initial(data)
        st = self._check_structure()
        scored = Scored.of(data, "validation", st.start)
        errors = []
        for i, v in enumerate(vectors):
            errors.append(split_error(st, data, scored, v, self._check_band()))
            progress("ridge", (i + 1) / len(vectors), f"factor {i + 1}/{len(vectors)}")
        if np.isfinite(errors).any():
            best = int(np.argmin(errors))
        else:
            best = len(vectors) - 1
            warnings.warn(
                "ridge: the free run diverges on the validation split for every factor tried; keeping the largest",
                stacklevel=2,
            )
        self.weights_ = vectors[best]
        self.ridge_ = {
            "alpha": factors[best],
            "validation_nmse": [None if not np.isfinite(e) else 100 * e for e in errors],
        }

    # ------------------------------------------------------------------ mse_inf (3.15, 6.3.2)
    def _refine(
        self, data: TrainingData, progress: Progress, warn: bool = True, initial: np.ndarray | None = None
    ) -> None:
        """Re-estimate the weights on the free-running error (``cost: mse_inf``, eq. 3.15), from the least-squares
        weights or from ``initial`` (``initial_weights``: a warm start); ``warn``: say so when the result still
        leaves the divergence band on the training data (the lag and degree search says it for the finalist it
        keeps, :meth:`_warn_if_diverging`)."""
        r = self.params.refinement
        st = self._structure()
        scored = Scored.of(data, "train", st.start)
        if scored.n <= self.weights_.size:
            raise ValueError(f"cost mse_inf: only {scored.n} scored training samples for {self.weights_.size} weights")
        self._check_initial(data)
        val = Scored.of(data, "validation", st.start) if data.has("validation") else None
        finite_clip = (np.maximum(self.clip_lo_, self._bounds[0]), np.minimum(self.clip_hi_, self._bounds[1]))
        penalty = None
        ridge_ = getattr(self, "ridge_", None)
        if ridge_ is not None:
            const = ~self.exponents_.any(axis=1)
            alpha = np.asarray(ridge_["alpha"])[self.term_output_]
            penalty = np.where(const, 0.0, np.sqrt(alpha / (scored.n * scored.var[self.term_output_])))
        problem = FreeRunProblem(st, data, scored, finite_clip, penalty)
        check, band = self._check_structure(), self._check_band()
        if initial is not None:
            self.weights_ = np.array(initial, dtype=np.float64)
        unstable = diverges(check, data, scored, self.weights_, band)
        mixes = [1.0 - i / r.ramp for i in range(1, r.ramp + 1)] if unstable else [0.0]

        def record(mix: float, w: np.ndarray, res) -> None:
            entry: dict[str, Any] = {
                "mix": float(mix),
                "train_cost": float(2 * res.cost),
                "nfev": int(res.nfev),
                "status": int(res.status),
            }
            if val is not None and mix == 0.0:
                e = split_error(check, data, val, w, band)
                entry["validation_nmse"] = None if not np.isfinite(e) else 100 * e
            self.refinement_.append(entry)
            progress("mse_inf", None, f"mix {mix:.2f}: cost {2 * res.cost:.4g} after {res.nfev} runs")

        first = self.weights_  # least squares, or the initial weights
        ls_cost = None if unstable else problem.cost(first)
        start: dict[str, Any] = {"mix": 1.0 if unstable else 0.0, "train_cost": ls_cost, "diverged": bool(unstable)}
        if val is not None:
            e = split_error(check, data, val, first, band)
            start["validation_nmse"] = None if not np.isfinite(e) else 100 * e
        if initial is not None:
            start["start"] = "initial weights"
        self.refinement_.append(start)
        w0 = first
        linear = None if initial is not None else steiglitz_mcbride(problem, first)
        if linear is not None and (ls_cost is None or linear[1] < ls_cost):
            if not diverges(check, data, scored, linear[0], band):
                # a linear model: the output-error start is nearer the free-run optimum than least squares
                w0, mixes = linear[0], [0.0]
                self.refinement_.append({"start": "steiglitz-mcbride", "train_cost": linear[1]})
        self.weights_ = refine(problem, w0, mixes, r.solver, r.max_nfev, r.tol, record)
        before, after = start.get("validation_nmse"), self.refinement_[-1].get("validation_nmse")
        if val is not None and before is not None and (after is None or after > before):
            # the validation split decides (A.3): the free-running estimate generalises worse here
            self.weights_ = first
            kept = "least squares" if initial is None else "initial weights"
            self.refinement_.append({"kept": kept, "validation_nmse": before})
        if warn:
            self._warn_if_diverging(data)

    def _warn_if_diverging(self, data: TrainingData) -> None:
        scored = Scored.of(data, "train", self.warmup)
        if diverges(self._check_structure(), data, scored, self.weights_, self._check_band()):
            warnings.warn(
                "cost mse_inf: the re-estimated model still leaves the divergence band (or needs its output clip) "
                "in free run on the training data; try ridge, a lower degree or fewer terms",
                stacklevel=3,
            )

    def _check_initial(self, data: TrainingData) -> None:
        L = self.warmup
        for i, s in enumerate(data.series):
            if L and not np.isfinite(s.y[:L]).all():
                raise ValueError(
                    f"the free run of recording {i + 1} starts from its first {L} measured outputs, which lie "
                    "in the test split; use initial: settled (or zeros) or put the test range later"
                )

    # ------------------------------------------------------------------ prediction
    def _initial(self, y_measured: np.ndarray | None, n: int) -> np.ndarray:
        L = min(self.warmup, n)
        if L == 0:
            return np.zeros((0, self.n_outputs_))
        have = 0 if y_measured is None else len(y_measured)
        Y = None if y_measured is None else np.asarray(y_measured, dtype=np.float64).reshape(have, -1)
        if Y is None or have < L or not np.isfinite(Y[:L]).all():
            raise ValueError(
                f"this NARX model starts its free run from the first {L} measured output samples "
                f"(initial: measured); got {have if Y is None else int(np.isfinite(Y[:L]).all(axis=1).sum())} "
                "finite ones"
            )
        return np.ascontiguousarray(Y[:L])

    def simulate(
        self, u: np.ndarray, y_measured: np.ndarray | None = None, bounds: tuple[np.ndarray, np.ndarray] | None = None
    ) -> Simulation:
        self.check_fitted()
        u = np.ascontiguousarray(u, dtype=np.float64)
        Y = self._initial(y_measured, u.shape[0])
        yhat, div = self._structure().run(u, Y, self.weights_, 0.0, bounds)
        return Simulation(yhat, None if div < 0 else int(div))

    def predict_one_step(self, u: np.ndarray, y_measured: np.ndarray) -> np.ndarray | None:
        """One-step-ahead predictions: every fed-back value is the measured one (mix = 1)."""
        self.check_fitted()
        u = np.ascontiguousarray(u, dtype=np.float64)
        Y = np.ascontiguousarray(y_measured, dtype=np.float64).reshape(u.shape[0], -1)
        self._initial(Y, u.shape[0])
        return self._structure().run(u, Y, self.weights_, 1.0)[0]

    # ------------------------------------------------------------------ persistence
    def to_arrays(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        src, ch, lag = self.embedding_.arrays()
        arrays = {
            "exponents": self.exponents_,
            "term_output": self.term_output_,
            "weights": self.weights_,
            "regressor_source": src,
            "regressor_channel": ch,
            "regressor_lag": lag,
            "clip_low": self.clip_lo_,
            "clip_high": self.clip_hi_,
        }
        attrs = {
            "regressor_names": [r.name for r in self.embedding_.regressors],
            "terms": self.terms_,
            "n_inputs": self.n_inputs_,
            "n_outputs": self.n_outputs_,
            "output_names": self.output_names_,
            "selection": self.selection_,
            "refinement": self.refinement_,
            "ridge": getattr(self, "ridge_", None),
        }
        return arrays, attrs

    @classmethod
    def from_arrays(cls, params: dict[str, Any], arrays: dict[str, np.ndarray], attrs: dict[str, Any]) -> Narx:
        self = cls(**params)
        names = list(attrs["regressor_names"])
        src, ch, lag = (
            np.asarray(arrays[k], dtype=np.int64) for k in ("regressor_source", "regressor_channel", "regressor_lag")
        )
        self.embedding_ = Embedding([Regressor(int(s), int(c), int(k), n) for s, c, k, n in zip(src, ch, lag, names)])
        self.exponents_ = np.asarray(arrays["exponents"], dtype=np.int64).reshape(-1, len(names))
        self.term_output_ = np.asarray(arrays["term_output"], dtype=np.int64)
        self.weights_ = np.asarray(arrays["weights"], dtype=np.float64)
        self.clip_lo_ = np.asarray(arrays["clip_low"], dtype=np.float64)
        self.clip_hi_ = np.asarray(arrays["clip_high"], dtype=np.float64)
        self.n_inputs_, self.n_outputs_ = int(attrs["n_inputs"]), int(attrs["n_outputs"])
        self.output_names_ = list(attrs["output_names"])
        self.selection_ = dict(attrs.get("selection") or {})
        self.refinement_ = list(attrs.get("refinement") or [])
        if attrs.get("ridge"):
            self.ridge_ = dict(attrs["ridge"])
        return self

    def check_data(self, input_names, output_names, splits) -> None:
        """Before a fit: the columns ``lags`` names exist, and the term selection has a stopping rule (a
        validation split with ``patience``, ``max_terms`` or ``threshold``; explicit ``terms`` need none)."""
        p = self.params
        if p.lags is not None:  # unknown names and output lag 0 raise here as in fit
            build_embedding(p.lag_table(), list(input_names), list(output_names), (), p.max_degree, p.constant)
        selects = p.terms is None
        validated = "validation" in splits and p.patience is not None
        if selects and not validated and p.max_terms is None and p.threshold is None:
            raise ValueError(
                "FOS needs a stopping rule: a validation split (data.split.validation, used with patience), "
                "max_terms or threshold"
            )

    def driven_system(self):
        """The free run as a driven system whose state is the past outputs (``plugins/narx/reliability.py``),
        for ``dynmodel reliability-check``: does the model forget the outputs it started from?"""
        from .reliability import NarxSystem

        self.check_fitted()
        return NarxSystem(
            self.embedding_,
            self.exponents_,
            self.term_output_,
            self.weights_,
            self.n_inputs_,
            self.n_outputs_,
            (self.clip_lo_, self.clip_hi_),
        )

    def summary(self) -> dict[str, Any]:
        info: dict[str, Any] = {
            "regressors": [r.label for r in self.embedding_.regressors],
            "selection": self.selection_.get("method"),
        }
        if "pool" in self.selection_:
            info["pool"] = self.selection_["pool"]
        for k, name in enumerate(self.output_names_):
            w = self.weights_[self.term_output_ == k]
            info[f"model {name}"] = " + ".join(
                f"{wi:.6g} {t}" if t != "1" else f"{wi:.6g}" for wi, t in zip(w, self.terms_[k])
            ).replace("+ -", "- ")
        info["warmup"] = self.warmup
        if np.isfinite(self.clip_lo_).any():
            info["bounds (model space)"] = [[float(a), float(b)] for a, b in zip(self.clip_lo_, self.clip_hi_)]
        ridge_ = getattr(self, "ridge_", None)
        if ridge_:
            info["ridge factor"] = ridge_["alpha"]
        if self.refinement_:
            last = self.refinement_[-1]
            info["mse_inf solves"] = sum(1 for e in self.refinement_[1:] if "mix" in e)
            if self.refinement_[0].get("diverged"):
                info["mse_inf error propagation"] = (
                    "the least-squares model diverged; mixture ramped to pure prediction"
                )
            if any(e.get("start") == "steiglitz-mcbride" for e in self.refinement_):
                info["mse_inf start"] = "Steiglitz-McBride iterations (a linear model: nearer its free-run optimum)"
            if last.get("kept"):
                info["mse_inf"] = "not kept: the least-squares weights validate better"
            if last.get("validation_nmse") is not None:
                info["mse_inf validation NMSE %"] = round(float(last["validation_nmse"]), 6)
        return info

    # ------------------------------------------------------------------ extensions (docs/plugins-extensions.md)
    @classmethod
    def extensions(cls, cause, ctx):
        from .extensions import extensions

        return extensions(cause, ctx)

    @classmethod
    def include_inputs(cls, channels, history, ctx):
        from .extensions import include_inputs

        return include_inputs(channels, history, ctx)

    # ------------------------------------------------------------------ family: auto (docs/plugins.md)
    @classmethod
    def search_space(cls, ctx, around=None):
        from .search import search_space

        return search_space(ctx, around)

    def frozen_config(self) -> dict[str, Any] | None:
        """The given parameters with the fitted structure frozen: its terms (``terms``, so no FOS and no lag or
        degree search) and its ridge factor (one factor for every output; ``ridge: auto`` chose it on
        validation); cost ``mse1`` when the validation kept the least-squares weights over the free-run ones. Else
        also a warm start (``warm``: its weights as ``initial_weights``), tried first when they were grown on the
        free-running error (``selection: free_run``) or started from given weights, else when the refit from least
        squares stalls.
        None when the outputs' ridge factors differ (one number cannot give them), or when the validation kept the
        weights grown on the last ``growth_window`` samples over those re-estimated on the whole training split
        (more samples would undo that choice), or for the constant alone."""
        self.check_fitted()
        if (self.selection_.get("window") or {}).get("weights") == "window":
            return None
        if not self.exponents_.any():  # the constant alone names no lag: nothing to fit again but a mean
            return None
        frozen = {k: v for k, v in self._given.items() if k not in _CHOOSING}
        frozen["terms"] = {name: list(terms) for name, terms in zip(self.output_names_, self.terms_)}
        ridge_ = getattr(self, "ridge_", None)
        if ridge_ is not None:
            alpha = np.unique(np.asarray(ridge_["alpha"], dtype=float))
            if alpha.size != 1:
                return None
            frozen["ridge"] = float(alpha[0])
        steps = getattr(self, "refinement_", [])
        least_squares = any(step.get("kept") == "least squares" for step in steps)
        grown = self.selection_.get("method") == "free_run" or any(s.get("start") == "initial weights" for s in steps)
        if least_squares or not (steps or grown):  # least-squares weights (cost mse1): nothing to start
            return {"params": frozen, "cost": "mse1" if least_squares else None}
        warm = {
            **frozen,
            "initial_weights": {
                name: [float(w) for w in self.weights_[self.term_output_ == k]]
                for k, name in enumerate(self.output_names_)
            },
        }
        # weights grown term by term on the free-running error: least squares is a poor start for them (Bouc-Wen:
        # refitted from least squares on every sample, 0.23 % free-run NMSE there against the grown model's 0.08 %)
        return {"params": frozen, "cost": None, "warm": warm, "warm_first": grown}

    @classmethod
    def full_work(cls, ctx, found):
        from .search import full_work

        return full_work(ctx, found)
