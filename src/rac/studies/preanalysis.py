"""``rac preanalyse``: the paper's pre-analysis over a grid of model settings (Section 5, Table 1).

For every combination of exponent (number representation), sensing period C1 and decision
period C2 the sweep answers, on the model built at that setting:

- Qa — ``Pr[<=T](<> fabs(true_x - x) >= sensor_error)``: how often the sensed position drifts
  from the ground truth (N simulated runs, Clopper–Pearson interval);
- Qb — a run that is never unsafe exists (``E[] !collide() && !offroad()``);
- Qc — a run that stays safe until it reaches the goal exists (``E<>`` on the graph whose unsafe
  states end a run), and ``qc_horizon``: one of them also stays safe to the horizon (the table says
  which; :func:`rac.engine.storm.safe_reach`, the same words as ``rac verify``'s Qc message);
- Qd — the safety shield exists (``control: A[] !collide() && !offroad()``), with the states
  explored and the time;
- Fig. 7 — N runs under the shield; per run the smallest distance to an obstacle, *sensed*
  (``mindist()`` on the model's significands, what the shield sees) and *true* (the same
  distance for the ground truth, integrated finely and measured at exponent 4 at every CommonRoad
  time step, also between samples; more often where the time steps do not divide the sensing
  period). A run that meets no obstacle (``mindist()`` reads
  :data:`~rac.model.native.NO_OBSTACLE` at every sample) has no smallest distance: NaN in the row,
  null in the JSON, "no obstacle" in the table and the plots; ``obstacles`` counts the scenario's.

The coarse settings' point: the shield keeps the *sensed* distance safe, but a coarse
representation or a long period lets the *true* distance drop below the threshold.
"""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import math
import re
import time
from collections.abc import Callable, Iterator
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from rac import ir
from rac.compiler import CompileResult
from rac.core.diagnostics import RacError, counted, short_number
from rac.core.numbers import samples_of
from rac.engine import storm
from rac.engine.budget import (
    VALUE_BYTES,
    BudgetExceeded,
    EstimateExceeded,
    TimeExceeded,
    TimeLimit,
    check_estimate,
    out_of_memory,
)
from rac.engine.shield import synthesise
from rac.engine.simulate import Limits, integrate_truth, simulate
from rac.engine.stats import clopper_pearson
from rac.ir.significands import off_grid, vanishing
from rac.ir.vocabulary import SETTINGS
from rac.model.batch import BatchModel
from rac.model.checks import goal_never
from rac.model.commonroad import Scenario
from rac.model.data import ModelData, ModelRangeError, build_model_data
from rac.model.native import NEGATIVE_DISTANCE_TEXT, NO_OBSTACLE
from rac.model.sample import MOTION, Ego
from rac.verify.context import over_budget

__all__ = ["ANSWERS", "SWEEP_PLOT", "Row", "SweepError", "answered", "earlier_plots", "render_table", "sweep"]

#: One row of the sweep (JSON-shaped: the CLI prints it as JSON and as a table).
Row = dict[str, Any]
#: A setting's answers, by their keys in its row.
ANSWERS = ("qa", "qb", "qc", "qd")


def answered(row: Row) -> str:
    """How far a setting's ``row`` is answered: ``"fully"`` (no error), ``"partly"`` (an error, and some of
    :data:`ANSWERS`: e.g. Qa's runs left int32 and Qb-Qd came from the exploration) or ``"not"``."""
    if "error" not in row:
        return "fully"
    return "partly" if any(row.get(key) is not None for key in ANSWERS) else "not"

#: The exponent at which true distances are measured (0.1 mm at base 10).
TRUTH_EXPONENT = 4
#: The most points a Fig. 7 plot draws per run. A short ``timeStepSize`` gives millions of true
#: distances per run, which matplotlib draws for many minutes (100 runs of 300,000: over ten).
PLOT_POINTS = 2000
#: The sweep's plot of every setting's runs, in the output folder beside the settings' own (:func:`_plot_name`).
SWEEP_PLOT = "sweep.png"
#: Exactly the names :func:`_plot_name` gives (``{:g}`` of a positive number: ``0.5``, ``1``, ``1e-05``, ``1.5e+06``).
_PLOT_FILE = re.compile(r"fig7_e\d+_c1_\d+(\.\d+)?(e[+-]\d+)?_c2_\d+(\.\d+)?(e[+-]\d+)?\.png")


def _plot_name(spec: ir.ModelSpec) -> str:
    """The file name of a setting's Fig. 7 plot: its settings, e.g. ``fig7_e2_c1_0.5_c2_1.png``."""
    return f"fig7_e{spec.exponent}_c1_{float(spec.sense_period):g}_c2_{float(spec.decide_period):g}.png"


def earlier_plots(out_dir: Path) -> list[Path]:
    """The plots a run of the sweep writes that ``out_dir`` holds (:func:`_plot_name`'s and :data:`SWEEP_PLOT`),
    in name order; none when it cannot be read."""
    try:
        names = sorted(entry.name for entry in out_dir.iterdir())
    except OSError:
        return []
    return [out_dir / name for name in names
            if (name == SWEEP_PLOT or _PLOT_FILE.fullmatch(name)) and (out_dir / name).is_file()]


class SweepError(RacError, ValueError):
    """Bad sweep arguments (a list that does not parse, a value out of its range, a horizon that is not
    a whole number of sensing periods)."""


def _values(text: str | None, default: Fraction, what: str, *, whole: bool = False,
            at_most: Fraction | None = None, bound: str = "") -> list[Fraction]:
    """The comma-separated list ``text`` of positive numbers (whole ones with ``whole``), each at most
    ``at_most`` (``bound`` names it); ``[default]`` when ``text`` is None. :class:`SweepError` names
    ``what`` and the item otherwise."""
    if text is None:
        return [default]
    out = []
    for item in text.split(","):
        try:
            value = Fraction(item.strip())
        except (ValueError, ZeroDivisionError):
            raise SweepError(f"{what}: {item.strip()!r} is not a number") from None
        if value <= 0 or (whole and value.denominator != 1):
            raise SweepError(f"{what}: {item.strip()!r} must be a positive {'whole ' if whole else ''}number")
        if at_most is not None and value > at_most:  # before any float(): 1e400 has none
            raise SweepError(f"{what}: {item.strip()!r} must be at most {bound or short_number(at_most)}")
        if value in out:  # a row twice would be run twice and shown twice
            raise SweepError(f"{what}: {item.strip()!r} is given twice (as {short_number(value)})")
        out.append(value)
    return out


def _check_horizon(horizon: Fraction, senses: list[Fraction]) -> None:
    """:class:`SweepError` unless ``horizon`` (``--horizon``) is a whole number of every sensing period
    C1 of the grid, of at most :data:`~rac.core.numbers.INT32_MAX` samples (the model counts them in
    int32), as ``rac verify`` requires of its sample period."""
    for sense in senses:
        try:
            samples_of(horizon, sense, period_name="C1 = ")
        except ValueError as exc:
            raise SweepError(str(exc)) from None


def _substeps_per_sample(spec: ir.ModelSpec, dt: float) -> int:
    """How many steps the true distances take per sensing period: one per CommonRoad time step it
    spans, ``ceil(C1 / dt)`` where that is not a whole number (a 0.5 s period over steps of 0.04 s:
    13), so that they are never measured less often than the scenario's states change; 1 when a
    time step is longer than the period."""
    ratio = Fraction(spec.sense_period) / Fraction(dt).limit_denominator(10**6)
    return max(1, math.ceil(ratio))


def _unheld(spec: ir.ModelSpec) -> str | None:
    """Why the model at ``spec``'s exponent is not the file's (what ``rac check`` reports at that
    exponent as E0702 and E0706): a positive setting truncated to 0, or an action off the significands;
    None when it is the file's model."""
    where = f"at base {spec.base}, exponent {spec.exponent}"
    values = {name: value for name in SETTINGS if isinstance(value := getattr(spec, name, None), Fraction)}
    lost = vanishing(values, spec.scale)
    if lost:
        return (f"{where}, " + ", ".join(f"`{name}` {short_number(values[name])}" for name in lost)
                + f" truncate{'s' * (len(lost) == 1)} to 0: the model would use 0, not the file's value "
                  "(rac check: E0702 at this exponent)")
    for action in spec.actions:
        if off_grid(action, spec.scale) is not None:
            return (f"{where}, action `{action.name}` in [{short_number(action.low)}, {short_number(action.high)}] "
                    f"step {short_number(action.step)} does not fall on whole significands (rac check: E0706 at "
                    "this exponent)")
    return None


def _truth_bytes(runs: int, samples: int, substeps: int) -> int:
    """The estimated peak bytes of :func:`_true_distances`: its ``(N, T*m+1)`` float64 distances and
    the copy of them that :func:`_smallest` masks (the model's own tables are small beside them)."""
    return 2 * runs * (samples * substeps + 1) * VALUE_BYTES


def _truth_exponent(scenario: Scenario, spec: ir.ModelSpec) -> int:
    """The exponent at which the true distances are measured: :data:`TRUTH_EXPONENT`, or, where the
    scenario overflows int32 there (coordinates of a real map in UTM, x ≈ 5e5 m, overflow beyond
    exponent 2), the finest below it at which the scenario fits: the row's own exponent at worst,
    which fits. Refusing the row instead withheld Qa-Qd, which do not need it."""
    for exponent in range(TRUTH_EXPONENT, spec.exponent, -1):
        try:
            build_model_data(scenario, dataclasses.replace(spec, exponent=exponent))
        except ModelRangeError:
            continue
        return exponent
    return min(TRUTH_EXPONENT, spec.exponent)


def _true_distances(result: CompileResult, spec: ir.ModelSpec, runs, data: ModelData,
                    quiet: bool = True, check: Callable[[], None] | None = None,
                    exponent: int = TRUTH_EXPONENT) -> np.ndarray:
    """``(N, T*m+1)`` distances of the ground truth to the nearest obstacle at every CommonRoad
    time step (``m`` per sensing period, :func:`_substeps_per_sample`), measured on a model at
    ``exponent`` (:func:`_truth_exponent`) whose sensing period is one such step — so a long period cannot
    hide a close encounter. A short ``timeStepSize`` makes that many steps: a bar counts them
    (``quiet``: none); ``check()`` is called after each sensing period's steps (a time limit's)."""
    # tqdm (via rac.output.progress): importing rac.studies.preanalysis stays light
    from rac.output.progress import Heartbeat, Progress

    scenario = result.scenario
    assert scenario is not None  # sweep() refuses a model without one
    m = _substeps_per_sample(spec, scenario.dt)
    fine = build_model_data(scenario, dataclasses.replace(
        spec, exponent=exponent, sense_period=spec.sense_period / m, decide_period=spec.sense_period / m))
    model = BatchModel(fine)
    scale = float(fine.scale)
    limits = Limits.of(data)
    n, samples = runs.truth.shape[0], runs.truth.shape[1]
    out = np.empty((n, (samples - 1) * m + 1))

    def distance(truth: np.ndarray, index: int) -> np.ndarray:
        ego = np.zeros((n, len(Ego)), dtype=np.int32)
        ego[:, MOTION] = np.trunc(np.clip(truth.T * scale, -2.1e9, 2.1e9)).astype(np.int64)
        return model.mindist(ego, index)

    truth = runs.truth[:, 0].T.copy()  # (5, n), as the integrator holds it
    out[:, 0] = distance(truth, 0)
    steps = (samples - 1) * m
    what = f"true distances, {counted(steps, 'step')} of {counted(n, 'run')}"
    if Heartbeat.active is not None:  # off a terminal, the progress lines name the work and its size
        Heartbeat.active.phase(what)
    with Progress(total=steps, desc=what, unit="steps", enabled=False if quiet else None) as bar:
        for k in range(samples - 1):
            jerk, turn = runs.states[:, k + 1, Ego.JERK] / data.scale, runs.states[:, k + 1, Ego.TURN] / data.scale
            for j in range(1, m + 1):
                truth = integrate_truth(truth, jerk, turn, data.period / m, max(1, 100 // m), limits)
                out[:, k * m + j] = distance(truth, k * m + j)
                bar.update()
            if check is not None:
                check()
    return out


@contextlib.contextmanager
def _simulating(what: str, samples: int, quiet: bool, limit: TimeLimit) -> Iterator[Callable[[int, int], None]]:
    """The ``progress`` of a setting's simulation (:func:`rac.engine.simulate.simulate`): a bar of its samples
    (``quiet``: none; off a terminal the heartbeat's count) and ``limit`` checked after each sample. A long
    horizon's runs take minutes: --max-seconds 5 let one run on for five minutes, without a count."""
    # tqdm (via rac.output.progress): importing rac.studies.preanalysis stays light
    from rac.output.progress import Progress, simulate_callback

    with Progress(total=samples, desc=what, unit="samples", enabled=False if quiet else None) as bar:
        yield simulate_callback(bar, limit.check)


@contextlib.contextmanager
def _exploring(quiet: bool, limit: TimeLimit) -> Iterator[Callable[[int, int, int], None]]:
    """The ``progress`` of a setting's exploration for Qb-Qd (:func:`rac.engine.shield.synthesise`): a bar of
    its states (``quiet``: none; off a terminal the heartbeat's count) and ``limit`` checked after each layer.
    It counted nothing: the longest step of a fine setting showed no bar, and off a terminal the progress
    lines went on saying Qa's samples."""
    # tqdm (via rac.output.progress): importing rac.studies.preanalysis stays light
    from rac.output.progress import Progress, explore_callback

    with Progress(desc="Qb-Qd: exploring", unit="states", enabled=False if quiet else None) as bar:
        count = explore_callback(bar)

        def progress(layer: int, frontier: int, total: int) -> None:
            count(layer, frontier, total)
            limit.check(layer, frontier, total)

        yield progress


def _row(result: CompileResult, spec: ir.ModelSpec, *, runs: int, horizon: Fraction, seed: int,
         max_states: int, max_bytes: int | None, threshold_factor: int, out_dir: Path | None,
         quiet: bool = True, max_seconds: float | None = None, found: Callable[[Row], None] | None = None) -> Row:
    row: Row = {"exponent": spec.exponent, "sense": float(spec.sense_period),
                              "decide": float(spec.decide_period)}
    limit = TimeLimit(max_seconds, what="this setting")
    try:
        return _answer(row, result, spec, runs=runs, horizon=horizon, seed=seed, max_states=max_states,
                       max_bytes=max_bytes, threshold_factor=threshold_factor, out_dir=out_dir, quiet=quiet,
                       limit=limit, found=found or (lambda _: None))
    except TimeExceeded as exc:  # the answers found before stay in the row; it is one without all its answers
        row["error"] = f"{exc} (--max-seconds)"
        row["time_limit"] = exc.limit  # what the command counts: the rows given up on time
        row.setdefault("seconds", time.perf_counter() - limit.started)
        return row


def _answer(row: Row, result: CompileResult, spec: ir.ModelSpec, *, runs: int, horizon: Fraction, seed: int,
            max_states: int, max_bytes: int | None, threshold_factor: int, out_dir: Path | None,
            quiet: bool, limit: TimeLimit, found: Callable[[Row], None]) -> Row:
    """Fill ``row`` with the setting's answers; :class:`TimeExceeded` between its steps once ``limit`` has
    passed (the answers found so far are in ``row`` then). ``found(row)`` after each answer (Qa; Qb-Qd)."""
    scenario = result.scenario
    assert scenario is not None  # sweep() refuses a model without one
    unheld = _unheld(spec)
    if unheld is not None:  # the file's model-block checks hold at its own exponent, not the grid's
        row["error"] = unheld
        return row
    try:
        data = build_model_data(scenario, spec)
    except ModelRangeError as exc:
        row["error"] = f"the scenario does not fit int32 at this exponent: {exc}"
        return row
    # the true distances: at their own exponent, whatever the row's; coarser only where the scenario's
    # coordinates overflow it (a map in UTM coordinates), and the row says so
    row["truth_exponent"] = _truth_exponent(scenario, spec)
    samples = int(horizon / spec.sense_period)
    row["samples"] = samples
    never = goal_never(data, samples)
    if never is not None:  # Qc is "no" for this reason alone, not for the traffic or the road
        row["goal_never"] = never.value
    row["obstacles"] = data.obstacle_count
    threshold = threshold_factor * data.td / data.scale
    row["threshold"] = threshold
    # The true distances are measured at every CommonRoad time step: a short timeStepSize makes
    # millions of them per run. Their memory is refused up front, before any of the setting's work.
    substeps = _substeps_per_sample(spec, scenario.dt)
    try:  # (at one step per sample the runs' own estimate, below, is the larger: it speaks)
        if substeps > 1:
            check_estimate(
                f"measuring the true distances of {counted(runs, 'run')} at every CommonRoad time step "
                f"({samples * substeps:,} steps per run: {substeps:,} per sensing period, the scenario's "
                f"timeStepSize being {scenario.dt:g} s)",
                _truth_bytes(runs, samples, substeps), max_bytes,
                "use fewer --runs, a shorter --horizon, or a scenario whose timeStepSize is not that short")
    except MemoryError as exc:
        row["error"] = _memory_error(exc)
        return row
    # Qa: sensor error, unshielded runs (UPPAAL's SMC semantics: uniform actions).
    try:
        with _simulating(f"Qa: {counted(runs, 'run')}", samples, quiet, limit) as progress:
            plain = simulate(data, runs=runs, horizon_samples=samples, seed=seed, max_bytes=max_bytes,
                             progress=progress)
    except MemoryError as exc:  # the budget's estimate, refused before anything is allocated (or the machine's)
        row["error"] = _memory_error(exc)
        return row
    except ModelRangeError as exc:  # Qa has no answer; the exploration may: its unsafe states end a run earlier
        row["error"] = _left_int32(exc, "Qa's runs")
    else:
        drift = np.abs(plain.truth[:, :, 0] - plain.states[:, :, Ego.X] / data.scale) >= float(spec.sensor_error)
        hits = int(drift.any(axis=1).sum())
        row["qa"] = clopper_pearson(hits, runs)
        found(row)
    limit.check()
    # Qb-Qd on the explored model (unsafe states end a run): the shield's own graph.
    t0 = time.perf_counter()
    try:
        with _exploring(quiet, limit) as progress:
            shield, masks = synthesise(data, samples, max_states=max_states, max_bytes=max_bytes, progress=progress)
    except MemoryError as exc:  # the budget (it says how far the exploration got), or the machine's memory
        row["error"] = _memory_error(exc)
        row["seconds"] = time.perf_counter() - t0
        return row
    except ModelRangeError as exc:  # Qa's answer, if any, stands
        row["error"] = "; ".join(filter(None, (row.get("error"), _left_int32(exc, "the exploration of Qb-Qd"))))
        row["seconds"] = time.perf_counter() - t0
        return row
    graph = shield.graph
    safe = graph.labels["safe"]
    row["qb"] = storm.decide(graph, "E[]", "safe").holds
    reach = storm.safe_reach(graph, safe & graph.labels["goal"])
    row["qc"], row["qc_horizon"] = reach.until.holds, reach.to_horizon
    row["qd"] = shield.shield_exists
    row["states"] = graph.n_states
    row["seconds"] = time.perf_counter() - t0
    found(row)
    if not shield.shield_exists:
        return row
    limit.check()
    # Fig. 7 under the shield: sensed and true distances.
    try:
        with _simulating(f"Fig. 7: {counted(runs, 'run')} under the shield", samples, quiet, limit) as progress:
            shielded = simulate(data, runs=runs, horizon_samples=samples, seed=seed + 1, policy=masks.masks_at,
                                max_bytes=max_bytes, progress=progress)  # the unshielded runs' estimate passed above
    except ModelRangeError as exc:  # Qa-Qd stand
        row["error"] = "; ".join(filter(None, (row.get("error"), _left_int32(exc, "Fig. 7's runs under the shield"))))
        return row
    model = BatchModel(data)
    sensed = np.stack([model.mindist(shielded.states[:, k], k) for k in range(samples + 1)], axis=1)
    limit.check()
    true = _true_distances(result, spec, shielded, data, quiet, limit.check, row["truth_exponent"])
    row["sensed_min"] = _smallest(sensed)
    row["true_min"] = _smallest(true)
    below = int((row["true_min"] < threshold).sum())
    row["below"] = below
    row["below_interval"] = clopper_pearson(below, runs)
    row["left_shield"] = int(shielded.left_policy.sum())
    if out_dir is not None:
        # matplotlib (via rac.output.plots): importing rac.studies.preanalysis stays light
        from rac.output.plots import plot_runs

        out_dir.mkdir(parents=True, exist_ok=True)
        name = _plot_name(spec)
        times = np.arange(true.shape[1]) * (data.period / (true.shape[1] - 1) * samples) if samples else np.zeros(1)
        times, drawn = _thinned(times, true)
        row["plot"] = str(plot_runs(times, drawn, out_dir / name, threshold=threshold,
                                    threshold_label=_td(threshold_factor), unit="m",
                                    ylabel="true distance to the nearest obstacle (m)",
                                    below_zero=NEGATIVE_DISTANCE_TEXT,
                                    title=f"exponent {spec.exponent}, C1 {float(spec.sense_period):g} s, "
                                          f"C2 {float(spec.decide_period):g} s: "
                                          f"{counted(runs, 'run')} under the shield"))
    return row


def sweep(result: CompileResult, *, exponents: str | None = None, senses: str | None = None,
          decides: str | None = None, runs: int = 100, horizon: Fraction | None = None, seed: int | None = None,
          max_states: int = 5_000_000, max_bytes: int | None = None, out_dir: Path | None = None,
          quiet: bool = True, threshold_factor: int = 1, done: list[Row] | None = None,
          max_seconds: float | None = None, partial: Callable[[list[Row], bool], None] | None = None,
          removed: list[Path] | None = None) -> list[Row]:
    """Answer Qa–Qd and the shielded Fig. 7 runs for every setting of the grid; one dict per setting.
    Each setting's dict is also appended to ``done`` (when given) as soon as it is found: after Ctrl-C
    (``KeyboardInterrupt``) it holds the settings finished before. ``partial`` (when given) is called after each
    answer with the rows as JSON data, the settings finished and, where the second argument is True, last the one
    running with its answers so far (a process killed from outside, ``rac sweep``'s task timeout, keeps what the
    last call had).

    ``exponents``, ``senses``, ``decides``: comma-separated lists (None: the file's own value).
    A decision period that is not a whole multiple of the sensing period is skipped with an
    ``error`` entry. ``out_dir`` receives one Fig. 7 plot per setting and ``sweep.png``; the plots an earlier
    run wrote there (:func:`earlier_plots`) are removed once the arguments are checked, before the first setting
    runs (they would stand beside this run's as if they were of it), and appended to ``removed`` (when given).
    ``max_seconds``
    limits each setting's time: past it (checked between its steps, per explored layer and per simulated
    sample) the setting is
    given up, its row keeping the answers found, an ``error`` that says so and ``time_limit`` (the seconds).
    :class:`SweepError` before any setting runs: a list that does not parse, an exponent outside the
    model's range, a period longer than the horizon, or a ``horizon`` given that is not a whole number
    of samples of every sensing period (or is more than :data:`~rac.core.numbers.INT32_MAX` of them)."""
    automaton = result.raise_for_errors()
    spec = automaton.model
    if spec is None or result.scenario is None:
        raise SweepError("the file has no `model` block")
    given = horizon is not None
    horizon = horizon if horizon is not None else Fraction(automaton.horizon)
    seed = seed if seed is not None else int(np.random.SeedSequence().generate_state(1)[0])
    setting = SETTINGS["exponent"]  # the model's own range of the setting
    assert setting.minimum is not None and setting.maximum is not None
    within = f"the horizon, {short_number(horizon)} s"
    axes = (_values(exponents, Fraction(spec.exponent), "--exponent", whole=True, at_most=setting.maximum,
                    bound=f"{setting.maximum} (the model's `exponent` lies in {setting.minimum}..{setting.maximum})"),
            _values(senses, spec.sense_period, "--sense", at_most=horizon, bound=within),
            _values(decides, spec.decide_period, "--decide", at_most=horizon, bound=within))
    if given:  # as rac verify's --horizon; the file's own horizon is taken as the file has it
        _check_horizon(horizon, axes[1])
    grid = list(itertools.product(*axes))
    if out_dir is not None:  # an earlier run's plots of other settings (or runs) are no part of this one
        for path in earlier_plots(out_dir):
            with contextlib.suppress(OSError):  # one that cannot be removed stays, not said as removed
                path.unlink()
                if removed is not None:
                    removed.append(path)
    rows: list[Row] = []

    def found(row: Row) -> None:  # the running setting's answers so far, after the settings finished
        if partial is not None:
            partial([*map(_jsonable, rows), _jsonable({**row, "seed": seed})], True)
    # tqdm (via rac.output.progress): importing rac.studies.preanalysis stays light
    from rac.output.progress import Heartbeat, Progress

    with Progress(total=len(grid), desc="settings", unit="settings", enabled=False if quiet else None) as bar:
        for exponent, sense, decide in grid:
            if Heartbeat.active is not None:  # off a terminal, the progress lines say which setting runs
                Heartbeat.active.phase(f"setting {bar.n + 1} of {len(grid)} (exponent {exponent}, "
                                       f"C1 {short_number(sense)} s, C2 {short_number(decide)} s)")
            variant = dataclasses.replace(spec, exponent=int(exponent), sense_period=sense, decide_period=decide)
            if (horizon / sense).denominator != 1:  # the file's own horizon (a given one was checked above)
                rows.append({"exponent": int(exponent), "sense": float(sense), "decide": float(decide),
                             "error": f"the horizon, {short_number(horizon)} s, is not a whole number of sensing "
                                      "periods (its runs would stop short of it)"})
            elif (decide / sense).denominator != 1:
                rows.append({"exponent": int(exponent), "sense": float(sense), "decide": float(decide),
                             "error": "the decision period is not a whole multiple of the sensing period"})
            else:
                try:
                    rows.append(_row(result, variant, runs=runs, horizon=horizon, seed=seed, max_states=max_states,
                                     max_bytes=max_bytes, threshold_factor=threshold_factor, out_dir=out_dir,
                                     quiet=quiet, max_seconds=max_seconds, found=found))
                except ModelRangeError as exc:  # a safety net: each step says where (_answer), keeping the others
                    rows.append({"exponent": int(exponent), "sense": float(sense), "decide": float(decide),
                                 "error": _left_int32(exc, "this setting")})
                except MemoryError as exc:
                    if isinstance(exc, RacError):  # a budget's refusal the row does not say: its callers do
                        raise
                    # the machine's memory (or `ulimit -v`) ran out before the budget said so: this setting
                    # has no answers, the others do
                    rows.append({"exponent": int(exponent), "sense": float(sense), "decide": float(decide),
                                 "error": _memory_error(exc)})
                rows[-1]["seed"] = seed
            if done is not None:
                done.append(_jsonable(rows[-1]))
            if partial is not None:
                partial([_jsonable(r) for r in rows], False)
            bar.update()
    if out_dir is not None:
        plotted = [r for r in rows if "true_min" in r]
        if plotted:
            # matplotlib (via rac.output.plots): importing rac.studies.preanalysis stays light
            from rac.output.plots import plot_sweep

            out_dir.mkdir(parents=True, exist_ok=True)
            sweep_rows = [{"exponent": r["exponent"], "sense": r["sense"], "decide": r["decide"],
                           "min_distances": list(r["true_min"]), "threshold": r["threshold"],
                           "probability": r["below_interval"]} for r in plotted]
            path = plot_sweep(sweep_rows, out_dir / SWEEP_PLOT, xlabel="smallest true distance of a run (m)",
                              threshold_label=_td(threshold_factor), unit="m", below_zero=NEGATIVE_DISTANCE_TEXT,
                              title="pre-analysis: runs under the shield")
            rows.append({"sweep_plot": str(path)})
    return [_jsonable(r) for r in rows]


def _left_int32(exc: ModelRangeError, where: str) -> str:
    """A setting's error for a sensed value that left int32 in ``where`` (UPPAAL's model aborts there too)."""
    return f"a sensed value left the int32 range at this exponent in {where}: {exc}"


def _memory_error(exc: MemoryError) -> str:
    """A setting's error for ``exc``: a budget's own words (:class:`~rac.engine.budget.BudgetExceeded`) with what
    to change, as rac verify says it (an estimate's refusal says it itself), or what running out of the machine's
    memory (or ``ulimit -v``) before the budget said so means."""
    if isinstance(exc, BudgetExceeded) and not isinstance(exc, EstimateExceeded):
        return over_budget(exc)  # it said how far it got, not which option to change
    return str(exc) if isinstance(exc, RacError) else out_of_memory(exc, "this setting")


def _thinned(times: np.ndarray, distances: np.ndarray, most: int = PLOT_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """``(times, distances)`` with at most ``most`` points per run for the plot: beyond it, consecutive
    stretches of the same length, each drawn as its smallest distance at its first time, so every
    run's lowest point (what the plot marks and counts against the threshold) stays."""
    n, points = distances.shape
    if points <= most:
        return times, distances
    size = math.ceil(points / most)
    padded = np.pad(distances, ((0, 0), (0, -points % size)), constant_values=np.nan)
    return times[::size], np.fmin.reduce(padded.reshape(n, -1, size), axis=2)  # fmin: the padding's NaN loses


def _smallest(distances: np.ndarray) -> np.ndarray:
    """Each run's smallest distance to an obstacle; NaN for a run that met none (every sample
    :data:`~rac.model.native.NO_OBSTACLE`)."""
    return np.fmin.reduce(np.where(distances == NO_OBSTACLE, np.nan, distances), axis=1)


def _td(factor: int) -> str:
    return "TD (collision)" if factor == 1 else f"{factor}·TD"


def _jsonable(row: Row) -> Row:
    out: Row = {}
    for key, value in row.items():
        if isinstance(value, (np.ndarray, tuple)):  # NaN (no obstacle) is null: JSON has no NaN
            out[key] = [round(float(v), 4) if math.isfinite(v) else None for v in value]
        elif isinstance(value, float):
            out[key] = value if math.isfinite(value) else None
        else:
            out[key] = value
    return out


def _yes(value: object) -> str:
    return "—" if value is None else ("true" if value else "false")


def _count(value: int | None) -> str:
    return "—" if value is None else f"{value:,}"  # an exploration stopped has no states to show, not 0


def _qc(row: Row) -> str:
    """Qc and what it means: safe until the goal only, or safe to the horizon too."""
    if not row.get("qc"):
        if row.get("qc") is not None and "goal_never" in row:  # W0722 at this setting: no run could reach it
            return f"false (`goal()` holds at no sample: {row['goal_never']})"
        return _yes(row.get("qc"))
    return "true (safe to the horizon)" if row.get("qc_horizon") else "true (safe until the goal only)"


def render_table(rows: list[Row]) -> str:
    """The sweep as a markdown table (what ``rac preanalyse`` prints)."""
    lines = ["| exponent | C1 (s) | C2 (s) | Qa: Pr sensor error | Qb | Qc | Qd | states | time (s) | "
             "runs below threshold under the shield (true distance) |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    notes = []
    for row in rows:
        if "exponent" not in row:
            if "sweep_plot" in row:
                notes.append(f"sweep plot: {row['sweep_plot']}")
            continue
        head = f"| {row['exponent']} | {row['sense']:g} | {row['decide']:g} |"
        if answered(row) == "not":  # Qa answered before the exploration stopped keeps its column
            lines.append(f"{head} {row['error']} | | | | | | |")
            continue
        qa = row.get("qa")
        qa_text = f"[{qa[0]:.3f}, {qa[1]:.3f}]" if qa else "—"
        below = str(row["error"]) if "error" in row else "—"  # given up after some answers (a time limit)
        measured = [v for v in row.get("true_min", ()) if v is not None and math.isfinite(v)]
        if "below" in row and not measured:
            below = f"no obstacle at any sample of the {counted(len(row['true_min']), 'run')}: no distance to measure"
        elif "below" in row:
            interval = row["below_interval"]
            below = (f"{row['below']} of {len(row['true_min'])} (Pr in [{interval[0]:.3f}, {interval[1]:.3f}]); "
                     f"min {min(measured):.2f} m vs {row['threshold']:g} m")
            if row.get("truth_exponent", TRUTH_EXPONENT) < TRUTH_EXPONENT:
                below += (f" (measured at exponent {row['truth_exponent']}: the scenario overflows int32 at "
                          f"exponent {TRUTH_EXPONENT})")
        lines.append(f"{head} {qa_text} | {_yes(row.get('qb'))} | {_qc(row)} | {_yes(row.get('qd'))} | "
                     f"{_count(row.get('states'))} | {row.get('seconds', 0):.2f} | {below} |")
    return "\n".join(lines + ([""] + notes if notes else []))
