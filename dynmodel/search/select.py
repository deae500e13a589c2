"""How the search judges its candidates: scores over seeds and folds, and the choice that protects the user.

A candidate's **score** at a level (screening, or the final layout) is its validation free-run NMSE (%):
the folds of a cross-validation pooled as one validation split (:func:`pooled`), then the **median over seeds** for a random family (a fit
that failed or diverged counts as infinitely bad, so one lucky draw cannot carry a configuration, and one
unlucky one cannot sink it). The seed whose score is that median gives the model that is kept.

The **choice** (:func:`choose`), in order:

1. a candidate whose free run leaves the output band on any split's *input* (:mod:`.checks`, widened with the
   input's excursion when the system is about linear), or strays from the output when started from measured
   outputs inside the training and validation data (:func:`.checks.measured_starts`; for a random
   family, on at least half of its seeds; for the blocked cross-validation, with half of its fold models or
   more) is rejected, whatever its validation error (the model that is kept is checked on
   its own as well);
2. among the rest, the lowest score is the reference point; a model that ignores its input is set aside
   when one that uses it scores within :data:`ABOUT_AS_WELL` of that; so is, when the system is about linear,
   a model whose output an input drives into an output clip beyond the strict band (its peaks cut flat there,
   ``Summary.clipped``) when one without scores within :data:`ABOUT_AS_WELL` (a linear plant tested beyond
   its training amplitude: a linear NARX model with its default clip validated as well as an unclipped one and
   scored 0.26 % test NMSE against 0.0003 %); the clip stays where nothing without one validates as well (a
   cart whose position drifts beyond its training range: every model that validated well met its clip there);
   and, when the test inputs leave the training range by more than :data:`EXTRAPOLATION`, a model whose free
   run remembers the outputs it started from (:func:`.checks.start_memory`: a second attractor or a mode that
   never settles; the reliability of thesis definition 4.4) when one shown to forget them scores within
   :data:`ABOUT_AS_WELL`; a network that reads no measured output shows neither (Silverbox: the degree-4 model
   validated best and tested 0.55 mV on the arrow's tail; a 42-term degree-3 model that forgets its start
   validated 11 % worse and tested 0.31 mV); and a model whose fits (seeds, folds) part ways on the test
   inputs by more than its validation shows (:func:`parts_ways`: a quarter of their spread there, a floor of
   their test error, above its score and :data:`SPREAD_FLOOR`; on a hold-out split the floor all but one seed
   exceed, :func:`fits_floor`) when one whose as many fits agree there (:func:`agrees`, the median pair) scores
   within :data:`ABOUT_AS_WELL` (held steps of another hold time on the test: an internal network, the simplest
   in the tie, validated at 0.2945 %, its seeds and folds erring by at least 0.41 % on the test inputs, and
   tested 0.71 %; a larger one validated at 0.292 % with fits that agreed and tested 0.055 %); and, on a hold-out
   split, a candidate whose seeds part ways there so far that all but one err by more than its validation error
   and more than one whose as many fits agree there validates (:func:`below_floor`, whatever its gap to the best:
   an internal network validated at 0.048 %, two of its three seeds erring by at least 0.39 % on held steps of
   another hold time, and tested 24.9 %; an external one whose seeds agreed validated at 0.111 % and tested 0.83 %),
   or a deterministic one whose validation error and the floor its refit on every sample sets there
   (:func:`refit_floor`) both lie below it (:func:`vouches`: every internal network parted ways on a Wiener
   saturation, the one kept tested 1.51 %; the NARX default, its refit 0.012 % from its validated fit there,
   validated at 0.042 % and tested 0.10 %);
3. candidates within a tie of the lowest score count as equal and the simplest of them wins: the tie is
   :data:`TIE` (1 %) normally, and :data:`CAUTIOUS_TIE` (10 %) when the validation cannot be trusted
   to rank finely: a short validation (cross-validated, or fewer than ``short`` scored samples), test
   inputs that leave the training range by more than :data:`EXTRAPOLATION` of its width, or no candidate
   that beats the linear reference by :data:`REFERENCE_MARGIN`. When the only reasons are the last, or a
   short validation that was cross-validated, a candidate stays out of the tie if it validates worse than
   the best by more than :data:`RESOLVED` standard errors of a paired comparison (:func:`paired_difference`):
   block by block, or fold by fold when cross-validated. The validation resolves that difference. Not for
   a short hold-out split (no folds to compare), nor when the test inputs leave the training range or
   recordings are left out in turn: validation cannot rank extrapolation. The report says when the simpler
   one was preferred, and why. Where the simplest's fits part ways on the test inputs (:func:`parts_ways`), the
   tie member with as many fits whose least test error (:func:`least_test_error`: its score or its fits' floor,
   the larger) is the lowest is chosen instead, if that lies below the simplest's floor (:func:`held_in_tie`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .checks import failed_split, forgets, median_difference, pair_differences, remembers

TIE = 0.01
CAUTIOUS_TIE = 0.10
ABOUT_AS_WELL = 1.25
#: a clear margin over the linear reference: at most this fraction of its NMSE
REFERENCE_MARGIN = 0.9
#: inputs beyond the training range by this fraction of its width make the search cautious
EXTRAPOLATION = 0.05
#: input dependence below which a model ignores its input (as :data:`dynmodel.usefulness.INPUT_DEPENDENCE`)
IGNORES_INPUT = 0.01
#: a block-wise difference larger than this many standard errors is resolved by the validation
RESOLVED = 2.0
#: a validation NMSE (%) from which even the best model is called poor
POOR = 50.0
#: the chosen candidate's fits part ways on the test inputs (:func:`.checks.spread`): say so when the floor of their
#: test error that implies (a quarter of the spread) is this many times its validation error and at least SPREAD_FLOOR
#: %. On the fresh population (seeds 300) it fired on four searches behind the best default, whose test errors were
#: 1.9 - 59x their validation errors (sys2, sys14, sys20, sys21), and on no other; at 0.0024 % a four-fold NARX
#: model's floor stood far above its refit's test error (8.4e-7 %): the refit on every sample can do better than the
#: fits on parts
SPREAD_NOTE = 3.0
SPREAD_FLOOR = 0.01


@dataclass
class Summary:
    """A candidate at one level: its score and what its fits showed."""

    score: float  # inf: no usable fit
    ok: bool  # passes the band checks (majority of seeds)
    dependence: float | None
    complexity: float | None
    seeds: dict[int, float]  # seed -> score (mean over folds)
    median_seed: int | None
    failure: str | None = None  # why the band check failed (the median seed's first failure)
    status: str = "ok"  # ok | diverged | error
    message: str | None = None
    fits: int = 0
    seconds: float = 0.0
    blocks: np.ndarray | None = None  # the median seed's score over validation blocks (:func:`block_scores`)
    blocks_on: tuple = ()  # the views (layouts) those blocks lie in: only blocks of the same views are compared
    continued: np.ndarray | None = None  # the same blocks of the continued run alone, where a fresh start was mixed in
    nonlinearity: float | None = None  # how far from affine in its input (median over fits)
    #: how far its free run remembers the outputs it started from (:func:`.checks.start_memory`, median over the
    #: median seed's fits; None: it reads no measured output)
    memory: float | None = None
    #: under the linear-system band, the split whose input drives the run kept to an output clip (the median seed's
    #: fits), else None (:func:`.checks.band_checks`)
    clipped: str | None = None
    #: how far its fits (seeds, folds) part ways on the test inputs (:func:`.checks.spread`, % of the training
    #: output variance; None: fewer than two fits, or no test split)
    spread: float | None = None
    #: the closest pair of those fits there (the smallest of :func:`.checks.pair_differences`; None as ``spread``)
    closest: float | None = None
    #: a deterministic candidate on a hold-out split: how far its refit on every training and validation sample (the
    #: model it would keep) departs from its validated fit on the test inputs (as ``spread``; None: not refitted,
    #: :meth:`.run.Search._stage_refit_agreement`)
    refit_apart: float | None = None

    @property
    def finite(self) -> bool:
        return math.isfinite(self.score)

    def to_json(self) -> dict[str, Any]:
        return {
            "score": self.score if self.finite else None,
            "band_ok": self.ok,
            "input_dependence": self.dependence,
            "input_nonlinearity": self.nonlinearity,
            "start_memory": self.memory if self.memory is None or math.isfinite(self.memory) else "inf",
            "clipped_on": self.clipped,
            "test_spread": self.spread,
            "test_spread_closest": self.closest,
            "test_refit_apart": self.refit_apart,
            "complexity": self.complexity,
            "seeds": {str(k): (v if math.isfinite(v) else None) for k, v in self.seeds.items()},
            "median_seed": self.median_seed,
            "failure": self.failure,
            "status": self.status,
            "message": self.message,
            "fits": self.fits,
            "seconds": round(self.seconds, 3),
        }


def _median_seed(scores: dict[int, float]) -> tuple[float, int | None]:
    """The median score over seeds and its seed (the upper median for an even count: never the better of two
    draws; ties broken by the smaller seed)."""
    if not scores:
        return math.inf, None
    ordered = sorted(scores.items(), key=lambda kv: (kv[1], kv[0]))
    seed, value = ordered[len(ordered) // 2]
    return value, seed


def _layout_kind(results: list[Any]) -> str | None:
    """The layout kind (``fold``, ``recording``, ...) all ``results`` share, else None."""
    kinds = {(r.layout or {}).get("kind") for r in results}
    return kinds.pop() if len(kinds) == 1 else None


def _denominators(results: list[Any]) -> np.ndarray | None:
    """Per output, what the squared errors of ``results`` (several folds) are divided by for one pooled NMSE
    (see :func:`pooled`); None when a result has no moments."""
    moments = [r.moments for r in results]
    if any(m is None for m in moments):
        return None
    if _layout_kind(results) == "recording":
        # recordings at other operating points (pressures, loads) differ in level: the variance of all of
        # them together is mostly that spread, which any model of the right level gets for free (on the
        # seal data, an output-error model pooled 0.18 % and scored 8.6 % on a new pressure). Each recording
        # is normalised by its own variance, as a test recording is: sum of errors / sum of n_i var_i
        within = np.sum([np.asarray(m["sumsq"]) - np.asarray(m["sum"]) ** 2 / m["n"] for m in moments], axis=0)
        return np.maximum(within, np.finfo(float).tiny)
    n = sum(m["n"] for m in moments)
    mean = np.sum([m["sum"] for m in moments], axis=0) / n
    var = np.sum([m["sumsq"] for m in moments], axis=0) / n - mean**2
    return n * np.maximum(var, np.finfo(float).tiny)


def pooled(results: list[Any]) -> float:
    """One validation NMSE (%) of several folds: their squared errors summed and divided by the variance of
    every fold's measured validation output taken together (mean over outputs), as if the folds were one
    validation split. A fold of small output variance then weighs by its error, not by its own variance (per
    fold NMSEs of a slow system can be huge on a quiet block). Recordings left out in turn: divided by the sum
    of each recording's own variance times its samples instead (their levels differ by operating point, a
    spread no test recording is scored against). One result: its own score."""
    if len(results) == 1:
        return float(results[0].score)
    score = moment_score(results)
    return float(np.mean([r.score for r in results])) if score is None else score


def moment_score(results: list[Any]) -> float | None:
    """The NMSE (%) of the squared errors summed in ``results``' moments over their pooled denominators
    (:func:`pooled`), mean over outputs (one result: its NMSE from its own moments, where a fresh start may be
    mixed into the errors). None when a result has no moments."""
    denominators = _denominators(results)
    if denominators is None:
        return None
    sse = np.sum([r.moments["sse"] for r in results], axis=0)
    return float(np.mean(100.0 * sse / denominators))


def block_scores(results: list[Any], errors: str = "sse") -> np.ndarray | None:
    """The pooled validation NMSE (%) of ``results`` (the folds of one seed, in key order) split over the
    consecutive blocks of every fold (:data:`.worker.BLOCKS` each): block ``b`` holds its squared errors over
    the pooled denominator, scaled to the block's full size where a warmup left samples out, so that the
    blocks sum to about the score and two candidates' blocks cover the same samples; NaN for a block a
    warmup left entirely unscored. ``errors``: ``sse`` (the errors scored) or ``continued`` (those of the
    continued run alone, before a fresh start was mixed in). None without those blocks."""
    denominators = _denominators(results)
    if denominators is None or any(errors not in (r.moments.get("blocks") or {}) for r in results):
        return None
    parts = []
    for r in results:
        b = r.moments["blocks"]
        n, full = np.asarray(b["n"], dtype=float), np.asarray(b["full"], dtype=float)
        scale = np.divide(full, n, out=np.full_like(full, np.nan), where=n > 0)  # NaN: a block not scored
        parts.append(np.mean(100.0 * np.asarray(b[errors]) * scale[:, None] / denominators, axis=1))
    return np.concatenate(parts)


def paired_difference(a: Summary, b: Summary, group: int = 1) -> tuple[float, float] | None:
    """How much worse ``a`` validates than ``b`` summed over the same blocks, and the standard error of that
    sum from the spread of the block-wise differences (a paired comparison: the noise both candidates see
    cancels block by block, what differs between the models does not). When both scores mix in a fresh
    start (the test recordings start runs of their own, :func:`.worker.fresh_weight`), the spread is that of
    the continued runs' block differences: a start-up transient sits in the first block of every validation
    run as it does on every test recording, a difference the models make each time, not noise (a linear
    output-error model started from rest: 0.16 of its 0.24 % excess in one block of ten, which the spread of
    the mixed blocks took for noise). ``group``: consecutive blocks summed into one unit before the spread is
    taken (a fold's blocks in a blocked cross-validation: the blocks of one short fold are correlated, so
    their spread would understate the noise; folds apart from each other much less so). None unless both
    were validated on the same views, in as many blocks (a whole number of groups), and at least three units
    that both scored."""
    if a.blocks is None or b.blocks is None or a.blocks_on != b.blocks_on or a.blocks.shape != b.blocks.shape:
        return None
    d = a.blocks - b.blocks
    both = np.isfinite(d)  # the blocks both scored (a long warmup can leave the first unscored)
    spread = d
    if a.continued is not None and b.continued is not None and a.continued.shape == d.shape == b.continued.shape:
        spread = a.continued - b.continued
    if group > 1:
        if d.size % group:
            return None  # not whole folds: compared block by block, a short fold's blocks would pass for independent
        d = np.where(both, d, 0.0).reshape(-1, group).sum(axis=1)
        spread = np.where(both, spread, 0.0).reshape(-1, group).sum(axis=1)
        both = both.reshape(-1, group).any(axis=1)
    if both.sum() < 3:
        return None
    return float(d[both].sum()), float(np.sqrt(both.sum()) * spread[both].std(ddof=1))


def summarize(results: list[Any]) -> Summary | None:
    """Aggregate the fit results of one candidate at one level (several seeds, several folds)."""
    fits = [r for r in results if r.kind == "fit"]
    if not fits:
        return None
    by_seed: dict[int, list[Any]] = {}
    for r in fits:
        by_seed.setdefault(int(r.seed or 0), []).append(r)
    scores: dict[int, float] = {}
    ok_seeds: dict[int, bool] = {}
    for seed, rs in sorted(by_seed.items()):
        vals = [r.score for r in rs]
        usable = all(v is not None and math.isfinite(v) and r.status == "ok" for v, r in zip(vals, rs))
        scores[seed] = pooled(rs) if usable else math.inf
        failed = sum(1 for r in rs if not r.checks.get("ok", False))
        # blocked cross-validation: fewer than half of the fold models may leave the band, as for seeds (a
        # model trained on part of a short record can diverge where the one fitted on all of it does not; the
        # kept model is checked on its own, strictly). Recordings left out, each its own operating point: none
        allowed = (len(rs) - 1) // 2 if _layout_kind(rs) == "fold" else 0
        ok_seeds[seed] = failed <= allowed and usable
    score, median = _median_seed(scores)
    blocks: np.ndarray | None = None
    continued: np.ndarray | None = None
    blocks_on: tuple = ()
    if median is not None and math.isfinite(scores[median]):
        blocks = block_scores(by_seed[median])
        continued = block_scores(by_seed[median], "continued")
        blocks_on = tuple(tuple(sorted(r.layout.items())) for r in by_seed[median])
    ok = sum(ok_seeds.values()) * 2 >= len(ok_seeds) and (median is None or ok_seeds.get(median, False))
    chosen = by_seed.get(median, fits) if median is not None else fits
    deps = [r.dependence for r in fits if r.dependence is not None]
    curved = [r.nonlinearity for r in fits if getattr(r, "nonlinearity", None) is not None]
    sizes = [r.complexity for r in fits if r.complexity is not None]
    memories = [r.memory for r in chosen if getattr(r, "memory", None) is not None]
    failure = next((failed_split(r.checks) for r in chosen if failed_split(r.checks)), None)
    if failure is None and not ok:
        failure = next((failed_split(r.checks) for r in fits if failed_split(r.checks)), None)
    apart = pair_differences([r.test_runs for r in fits if r.status == "ok" and getattr(r, "test_runs", None)])
    errors = [r for r in fits if r.status == "error"]
    diverged = [r for r in fits if r.status == "diverged"]
    status = "ok"
    message = None
    if not math.isfinite(score):
        status = "error" if len(errors) * 2 >= len(fits) else "diverged"
        bad = (errors or diverged or fits)[0]
        message = bad.message
    return Summary(
        score=score,
        ok=ok and math.isfinite(score),
        dependence=float(np.median(deps)) if deps else None,
        complexity=float(np.median(sizes)) if sizes else None,
        seeds=scores,
        median_seed=median,
        failure=failure,
        status=status,
        message=message,
        fits=len(fits),
        seconds=float(sum(r.seconds for r in fits)),
        blocks=blocks,
        blocks_on=blocks_on,
        continued=continued,
        nonlinearity=float(np.median(curved)) if curved else None,
        memory=float(np.median(memories)) if memories else None,
        clipped=next((r.checks["clipped"] for r in chosen if r.checks.get("clipped")), None),
        spread=median_difference(apart),
        closest=min(apart, default=None),
    )


@dataclass
class Choice:
    key: str | None
    notes: list[str] = field(default_factory=list)
    verdicts: dict[str, str] = field(default_factory=dict)  # key -> why not chosen (or "chosen")
    cautious: list[str] = field(default_factory=list)  # why the tie was widened
    #: every candidate left the output band somewhere: the best on validation is kept anyway (its final fit too)
    anyway: bool = False


def model_size(s: Summary) -> float:
    """A candidate's size for "the simpler one" (unknown: the largest)."""
    return s.complexity if s.complexity is not None else math.inf


def sound_within(keys: list[str], summaries: dict[str, Summary], sound, best: float) -> bool:
    """Does a candidate of ``keys`` with ``sound(summary)`` validate within :data:`ABOUT_AS_WELL` of the score
    ``best``?"""
    return any(sound(summaries[k]) and summaries[k].score <= ABOUT_AS_WELL * best for k in keys)


def _set_aside(eligible: list[str], summaries: dict[str, Summary], flawed, best: float, sound=None) -> list[str]:
    """The candidates of ``eligible`` (best first) with the flaw ``flawed(summary)``, when one shown to be
    without it (``sound(summary)``; default: not flawed) validates within :data:`ABOUT_AS_WELL` of the score
    ``best`` (:func:`sound_within`); [] otherwise (the flawed stay)."""
    if not sound_within(eligible, summaries, sound or (lambda s: not flawed(s)), best):
        return []
    return [k for k in eligible if flawed(summaries[k])]


def ignores_input(s: Summary) -> bool:
    return s.dependence is not None and s.dependence < IGNORES_INPUT


def spread_floor(s: Summary) -> float:
    """The least mean test error (NMSE %) its validated fits can have on the test inputs: a quarter of their
    spread there (:func:`.checks.spread`), 0 with fewer than two fits or no test split."""
    return s.spread / 4 if s.spread is not None else 0.0


def parted_words(s: Summary) -> str:
    """How far its fits part ways on the test inputs and the floor of their test error that implies, for a note."""
    return (
        f"their runs there differ by {s.spread:.3g} % of the training output variance (median over pairs of fits), "
        f"so they err there by at least {spread_floor(s):.3g} % on average"
    )


def seeds_only(s: Summary) -> bool:
    """Are its fits its seeds alone, each fitted on the same samples (a hold-out split), with a closest pair?"""
    return s.closest is not None and s.fits == len(s.seeds)


def fits_floor(s: Summary) -> float:
    """The floor its fits put under its test error (NMSE %): on a hold-out split, where the model kept is one more
    draw of its seeds, the one all but one seed exceed (:func:`kept_floor`: one wild seed of three does not raise
    it); otherwise (folds, recordings left out) the mean one of a pair (:func:`spread_floor`)."""
    return kept_floor(s) if seeds_only(s) else spread_floor(s)


def floor_words(s: Summary) -> str:
    """The floor :func:`fits_floor` reads and how, for a note."""
    if seeds_only(s):
        return (
            f"the closest two of its seeds differ there by {s.closest:.3g} % of the training output variance, so all "
            f"but one err there by at least {kept_floor(s):.3g} %"
        )
    return parted_words(s)


def parts_ways(s: Summary) -> bool:
    """Do its fits part ways on the test inputs by more than its validation shows: a test floor
    (:func:`fits_floor`) above both its score and :data:`SPREAD_FLOOR`?"""
    return fits_floor(s) > max(s.score, SPREAD_FLOOR)


def parted_seeds(s: Summary) -> bool:
    """On a hold-out split, do its seeds part ways on the test inputs so far that all but one err there by more than
    its validation error (:func:`parts_ways` read on :func:`kept_floor`)?"""
    return seeds_only(s) and parts_ways(s)


def agrees(s: Summary) -> bool:
    """Do its fits (two or more) agree on the test inputs: the floor of a pair of them, the median pair
    (:func:`spread_floor`), at most its validation error or :data:`SPREAD_FLOOR`? Not merely the absence of
    :func:`parts_ways`, which on a hold-out split reads the closest pair: two close seeds and a wild one are not
    a candidate whose seeds agree (seeds 2100's sys22: an internal network's closest two 0.12 % apart, below its
    validation error, its median pair 2.6 %; it tests at 0.90 %)."""
    return s.spread is not None and spread_floor(s) <= max(s.score, SPREAD_FLOOR)


def parted_aside(eligible: list[str], summaries: dict[str, Summary], best: float) -> list[str]:
    """The candidates of ``eligible`` whose fits part ways on the test inputs (:func:`parts_ways`) while one
    with as many fits (seeds x layouts, the same kind of evidence) that agree there validates within
    :data:`ABOUT_AS_WELL` of the score ``best``."""
    agreeing = {
        summaries[k].fits for k in eligible if agrees(summaries[k]) and summaries[k].score <= ABOUT_AS_WELL * best
    }
    return [k for k in eligible if parts_ways(summaries[k]) and summaries[k].fits in agreeing]


def kept_floor(s: Summary) -> float:
    """The least test error (NMSE %) of every fit but one, when each fit is one more draw of the model kept: a
    quarter of the closest pair's difference on the test inputs (two fits erring by less would differ by less,
    :func:`.checks.pair_differences`). Only on a hold-out split, where every fit is a seed fitted on the same
    samples and the model kept is its median seed fitted again: one wild seed of three does not raise it (the
    median pair does). 0 for folds, trained on fewer samples than the model kept: they can part ways where it
    does not (seeds 700's sys2: folds at 0.20 - 0.56 % and 1205 % on the test, the refit on every sample at
    0.126 %)."""
    if not seeds_only(s):
        return 0.0
    assert s.closest is not None  # seeds_only
    return s.closest / 4


def refit_floor(s: Summary) -> float | None:
    """A deterministic candidate's least test error (NMSE %) of one of its two fits, its validated fit and its
    refit on every sample (the model it would keep): a quarter of their difference on the test inputs
    (:func:`.checks.pair_differences`); None when it was not refitted."""
    return None if s.refit_apart is None else s.refit_apart / 4


def vouches(a: Summary, s: Summary, floor: float) -> bool:
    """Does ``a`` show that it will do better on the test than all but one of ``s``'s seeds, which err there by at
    least ``floor`` (:func:`kept_floor`)? Its as many fits agree there (:func:`agrees`) and it validates below that
    floor; or, deterministic, its validation error and the floor its refit sets (:func:`refit_floor`) both lie below
    it."""
    if agrees(a) and a.fits == s.fits:
        return a.score < floor
    again = refit_floor(a)
    return again is not None and max(a.score, again) < floor


def below_floor(eligible: list[str], summaries: dict[str, Summary]) -> dict[str, str]:
    """The candidates of ``eligible`` whose seeds part ways on the test inputs so far that every one but one errs
    there by more than its validation error (:func:`parted_seeds`), each with the best candidate that
    :func:`vouches` to do better there (key -> that candidate)."""
    out: dict[str, str] = {}
    for k in eligible:
        s = summaries[k]
        if not parted_seeds(s):
            continue
        better = [a for a in eligible if a != k and vouches(summaries[a], s, kept_floor(s))]
        if better:
            out[k] = better[0]
    return out


def vouch_words(a: Summary) -> str:
    """What shows that ``a`` (:func:`vouches`) holds on the test inputs, for a note."""
    if a.refit_apart is not None:  # a deterministic candidate (one fit: no seeds to agree)
        return (
            f"whose refit on every sample departs from its validated fit there by {a.refit_apart:.3g} % (so one of "
            f"the two errs there by at least {refit_floor(a):.3g} %)"
        )
    return "whose seeds agree there"


def least_test_error(s: Summary) -> float:
    """The least test error (NMSE %) its evidence allows: the larger of its validation error and the floor its fits
    put under its test error (:func:`fits_floor`)."""
    return max(s.score, fits_floor(s))


def held_in_tie(close: list[str], summaries: dict[str, Summary], simplest: str) -> str | None:
    """Within the tie ``close``, where the validation ranks nothing: when the fits of ``simplest`` part ways on the
    test inputs (:func:`parts_ways`), the tie member with as many fits (the same kind of evidence) whose
    :func:`least_test_error` is the lowest, if that lies below the floor of ``simplest`` (the simpler first among equals);
    None otherwise. Seeds 3700's sys21 (a Wiener exponential, test inputs 18 % beyond the training range): three
    degree-2 NARX models tie at 0.41 - 0.42 % on five folds; the simplest, a ridge model, had folds at least 5.3 %
    apart on the test and tested 31 %; the one clipped at the training range, folds at least 2.2 %, tests 7.4 %."""
    s0 = summaries[simplest]
    if not parts_ways(s0):
        return None
    alike = [k for k in close if k != simplest and summaries[k].fits == s0.fits and summaries[k].spread is not None]
    if not alike:
        return None
    held = min(alike, key=lambda k: (least_test_error(summaries[k]), model_size(summaries[k]), k))
    return held if least_test_error(summaries[held]) < fits_floor(s0) else None


def choose(
    summaries: dict[str, Summary],
    labels: dict[str, str],
    *,
    short_validation: str | None = None,
    excursion: float = 0.0,
    reference: float | None = None,
    uses_inputs: bool = True,
    fold_blocks: int = 0,
    parted: bool = True,
    set_apart: bool = True,
) -> Choice:
    """The winner among ``summaries`` (candidate key -> Summary at the deciding level), see the module
    docstring. ``labels``: key -> a short description for the notes. ``short_validation``: why the
    validation is short (None when it is not); ``excursion``: how far test inputs leave the training
    range; ``reference``: the linear reference's score at the same level; ``fold_blocks``: when the short
    validation is a blocked cross-validation, the blocks of each fold (the paired comparison sums them);
    ``parted``: weigh how the fits part ways on the test inputs (False: the choice without those steps);
    ``set_apart``: the step of those that sets aside the candidates whose fits part ways while as many fits of
    another agree (False: the choice without that step alone, to say what it changed)."""
    out = Choice(None)
    order = sorted(summaries, key=lambda k: (summaries[k].score, k))
    for k in order:
        s = summaries[k]
        if not s.finite:
            out.verdicts[k] = f"no usable fit ({s.status}: {s.message})" if s.message else f"no usable fit ({s.status})"
        elif not s.ok:
            out.verdicts[k] = f"rejected: {s.failure or 'leaves the output band'}"
    eligible = [k for k in order if summaries[k].finite and summaries[k].ok]
    if not eligible:
        finite = [k for k in order if summaries[k].finite]
        if not finite:
            out.notes.append("no candidate gave a usable model")
            return out
        eligible = finite[:1]
        out.anyway = True
        out.notes.append(
            "every candidate leaves the output band on some input (it diverges or extrapolates beyond plausible "
            f"outputs); kept the best on validation anyway: {labels[eligible[0]]}"
        )
    best = summaries[eligible[0]].score
    # a model that ignores its input, then one kept to an output clip where a linear system goes on, is set aside
    # when one without that flaw validates about as well
    ignoring = uses_inputs and ignores_input(summaries[eligible[0]])
    aside = _set_aside(eligible, summaries, ignores_input, best) if ignoring else []
    for k in aside:
        out.verdicts[k] = "set aside: ignores its input while a model that uses it validates about as well"
    if aside:
        out.notes.append(
            f"{labels[eligible[0]]} validated best but ignores its input; a model that uses the input "
            f"validates within {100 * (ABOUT_AS_WELL - 1):.0f} % of it and is preferred"
        )
        eligible = [k for k in eligible if k not in aside]
        best = summaries[eligible[0]].score
    clipped = _set_aside(eligible, summaries, lambda s: bool(s.clipped), best)
    for k in clipped:
        out.verdicts[k] = (
            f"set aside: its output is cut flat at a clip on the {summaries[k].clipped} input, where the linear "
            "system's goes on, while an unclipped model validates about as well"
        )
    if clipped and summaries[clipped[0]].score <= best * (1 + CAUTIOUS_TIE):  # it could have been chosen: say why not
        out.notes.append(
            f"{labels[clipped[0]]} (validation NMSE {summaries[clipped[0]].score:.4g} %) has its output cut flat "
            f"at a clip on the {summaries[clipped[0]].clipped} input, where the linear reference's goes on (the "
            f"system is about linear); models without such a clip that validate within "
            f"{100 * (ABOUT_AS_WELL - 1):.0f} % of the best are preferred"
        )
    if clipped:
        eligible = [k for k in eligible if k not in clipped]
        best = summaries[eligible[0]].score
    # the test inputs leave the training range: a model that remembers where its run started (a second attractor,
    # often at its output clip, or a mode that never settles) is set aside when one that forgets its start validates
    # about as well
    if excursion > EXTRAPOLATION and remembers(summaries[eligible[0]].memory):
        aside = _set_aside(eligible, summaries, lambda s: remembers(s.memory), best, lambda s: forgets(s.memory))
        for k in aside:
            out.verdicts[k] = (
                "set aside: its free run remembers the outputs it started from, while a model that forgets them "
                "validates about as well and the test inputs leave the training range"
            )
        if aside:
            out.notes.append(
                f"{labels[eligible[0]]} validated best, but its free run remembers the outputs it started from "
                f"(runs started at the bottom and the top of the training output range stay "
                f"{summaries[eligible[0]].memory:.3g} output standard deviations apart from its own to the end: a "
                "second attractor, which an input beyond the training range can push the run into, or a mode that "
                "never settles); the test inputs leave the training range, so a model that forgets its start and "
                f"validates within {100 * (ABOUT_AS_WELL - 1):.0f} % of it is preferred"
            )
            eligible = [k for k in eligible if k not in aside]
            best = summaries[eligible[0]].score
    # fits that part ways on the test inputs (their error there cannot be below a quarter of that spread, which
    # exceeds their validation error): set aside when a candidate whose as many fits (the same kind of evidence)
    # agree there validates about as well
    apart = parted_aside(eligible, summaries, best) if parted and set_apart else []
    for k in apart:
        out.verdicts[k] = (
            "set aside: its fits part ways on the test inputs by more than its validation error, while a "
            "candidate whose as many fits agree there validates about as well"
        )
    if apart:
        eligible = [k for k in eligible if k not in apart]
        best = summaries[eligible[0]].score
    # seeds that part ways so far that all but one err on the test by more than an agreeing candidate validates
    beneath = below_floor(eligible, summaries) if parted else {}
    for k in beneath:
        out.verdicts[k] = (
            "set aside: its seeds part ways on the test inputs so far that all but one err there by more than a "
            "candidate that holds there validates"
        )
    if eligible[0] in beneath:
        first, agreeing = summaries[eligible[0]], summaries[beneath[eligible[0]]]
        out.notes.append(
            f"{labels[eligible[0]]} validated best (validation NMSE {first.score:.4g} %), but its {first.fits} seeds "
            f"part ways on the test inputs: {floor_words(first)}; "
            f"{labels[beneath[eligible[0]]]}, {vouch_words(agreeing)}, validates at {agreeing.score:.4g} %, below that: "
            "candidates whose seeds part ways like that are set aside"
        )
    if beneath:
        eligible = [k for k in eligible if k not in beneath]
        best = summaries[eligible[0]].score
    # the validation can itself say whether it resolves a gain when its only doubts are its size (a short
    # cross-validation: compared fold by fold) or a gain over the linear reference too small to trust at
    # once; not when the models will extrapolate, nor across recordings at other operating points
    pairable, group = True, 1
    if short_validation:
        out.cautious.append(short_validation)
        pairable, group = fold_blocks > 1, fold_blocks
    if excursion > EXTRAPOLATION:
        out.cautious.append(
            f"the validation or test inputs leave the training range by up to {100 * excursion:.0f} % of its width"
        )
        pairable = False
    top = eligible[0]
    if reference is not None and math.isfinite(reference) and not best <= REFERENCE_MARGIN * reference:
        out.cautious.append(
            f"no candidate beats the linear reference (validation NMSE {reference:.3g} %) by "
            f"{100 * (1 - REFERENCE_MARGIN):.0f} %"
        )
    paired = bool(out.cautious) and pairable
    by = "fold by fold" if group > 1 else "block by block"
    tie = CAUTIOUS_TIE if out.cautious else TIE
    close = [k for k in eligible if summaries[k].score <= best * (1 + tie) or summaries[k].score == best]
    resolved: set[str] = set()
    if paired:
        for k in close:
            worse = summaries[k].score > best * (1 + TIE)
            diff = paired_difference(summaries[k], summaries[top], group) if worse else None
            if diff is not None and diff[0] > RESOLVED * diff[1]:
                resolved.add(k)
        close = [k for k in close if k not in resolved]
    simplest = min(close, key=lambda k: (model_size(summaries[k]), summaries[k].score, k))
    # the validation ranks nothing within the tie; where the simplest's fits part ways on the test inputs, the tie
    # member whose as many fits hold there best is chosen, when even its least test error lies below that floor
    held = held_in_tie(close, summaries, simplest) if parted else None
    if (
        simplest == top
        and held is None
        and any(model_size(summaries[k]) < model_size(summaries[top]) for k in resolved)
    ):
        out.notes.append(
            f"{'; '.join(out.cautious)}, but {labels[top]} validates better than the simpler candidates {by} "
            f"(by more than {RESOLVED:g} standard errors of the difference), and is kept"
        )
    if held is not None:
        first, kept = summaries[simplest], summaries[held]
        out.notes.append(
            f"{labels[simplest]} is the simplest of the candidates that validate within "
            f"{100 * tie:.0f} % of the best (validation NMSE {first.score:.4g} %), but its {first.fits} fits part "
            f"ways on the test inputs: {floor_words(first)}; {labels[held]} validates within that tie "
            f"({kept.score:.4g} %) and its fits hold closer there (at least {fits_floor(kept):.3g} %), so it is chosen"
        )
        out.verdicts[simplest] = (
            "within the tie, the simplest, but its fits part ways on the test inputs by more than those of the one "
            "chosen"
        )
        simplest = held
    out.key = simplest
    if simplest != top and held is None:
        why = "; ".join(out.cautious) if out.cautious else "the difference is within 1 %"
        if paired:
            why += f", and the validation does not resolve the difference {by} (within {RESOLVED:g} standard errors)"
        out.notes.append(
            f"chose the simpler {labels[simplest]} (validation NMSE {summaries[simplest].score:.4g} %, size "
            f"{summaries[simplest].complexity:.0f}) over {labels[top]} ({summaries[top].score:.4g} %, size "
            f"{summaries[top].complexity:.0f}): {why}"
        )
    for k in eligible:
        if k == simplest:
            out.verdicts[k] = "chosen"
        elif k not in out.verdicts:
            out.verdicts[k] = "within the tie, larger" if k in close else "validates worse"
            if k in resolved:
                out.verdicts[k] = f"validates worse ({by})"
    if apart:  # say so when the step changed the choice
        inputs: dict[str, Any] = {
            "short_validation": short_validation,
            "excursion": excursion,
            "reference": reference,
            "uses_inputs": uses_inputs,
            "fold_blocks": fold_blocks,
        }
        plain = choose(summaries, labels, **inputs, parted=False)
        within = f"{100 * (ABOUT_AS_WELL - 1):.0f} %"
        agree = f"while a candidate whose as many fits agree there validates within {within} of the best"
        if plain.key in apart:
            first = summaries[plain.key]
            out.notes.append(
                f"{labels[plain.key]} (validation NMSE {first.score:.4g} %) would have been chosen, but its "
                f"{first.fits} fits part ways on the test inputs: {floor_words(first)}, {agree}; "
                f"{labels[simplest]} is chosen instead"
            )
        elif (  # the set-aside moved the tie's best: the choice without it alone differs (not another step's doing)
            plain.key is not None
            and plain.key != simplest
            and choose(summaries, labels, **inputs, set_apart=False).key != simplest
        ):
            first = summaries[apart[0]]
            out.notes.append(
                f"{labels[apart[0]]} validated best (validation NMSE {first.score:.4g} %), but its {first.fits} fits "
                f"part ways on the test inputs: {floor_words(first)}, {agree}; it is set aside and the tie is "
                f"measured from the next best, {labels[top]}, so {labels[simplest]} is chosen instead of "
                f"{labels[plain.key]}"
            )
    return out
