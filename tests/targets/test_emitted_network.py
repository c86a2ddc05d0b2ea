"""The whole emitted UPPAAL model, run transition by transition, against the engine's product.

``rac compile --target uppaal`` writes, for a file with a ``model`` block, a network of processes
(Timer, Controller, Action, Dynamics, one Obstacle per obstacle, the reward automaton;
docs/uppaal.md, "The whole model"); :func:`rac.engine.product.explore_product` claims to explore
exactly the discrete states of that network. This test runs the emitted network itself:

- every piece of UPPAAL code in it — the global declarations, each template's local declarations
  (per process instance, with its parameter), every guard, update, select range, invariant and
  rate — is compiled as C into one shared library (``cc``; channels left out, clocks as doubles)
  and called through ctypes, so integer division, ``%``, ``count++``, the bindings'
  ``read_inputs()`` and the model's functions run as compiled code, in UPPAAL's order;
- a small interpreter (:class:`Network`) plays UPPAAL's semantics on top: broadcast channels
  (every guard read in the state before the transition; the sender's update, then the receivers'
  in the order of the ``system`` line), committed locations, time passing to the Timer's deadline
  (hybrid clocks at their rates; the Dynamics process is the continuous ground truth, so only
  its location is kept). The Action's controllable ``select`` takes its ``(j, u)`` from a given
  action sequence; whatever else the model leaves open — the order in which several committed
  processes move — is explored completely at each instant, and every order must end in the same
  state (otherwise the emitted model has runs the engine does not have);
- along the same action sequence the engine's product graph is followed, and at every sample
  the network's discrete state is compared with the engine's: after ``accrue!`` with the
  ``accrued`` state, after ``read!`` with the ``read`` state or the new inputs, after ``sense!``
  with the ``sampled`` state, after ``finish!`` with the ``ended`` one (the sample index, the 7
  ego significands, the automaton's location, every input, every mirror, ``settled``), and the
  labels ``collide()``, ``offroad()``, ``goal()`` called in C with ``graph.labels``; the Obstacles'
  ``ox, oy`` after ``accrue!`` with ``obs_x(i), obs_y(i)`` and rac.model's obstacle positions, and
  their flow over a period with straight motion; the rewards' hybrid clocks with their mirrors.

Scenarios (each with the emitted model's own horizon, which the engine explores completely):
examples/left_turn/model.ra with a coarse action grid (jerk in {-2, 0, 2}, turn in {-0.4, 0, 0.4})
and a 1 s horizon (10 samples, 5 decisions); stdlib/driving.ra's automaton with the left turn's
bindings (``prev(dist_goal())`` among them) in the tiny scenario ``avoidable_obstacle`` (its whole
4 s horizon: 8 samples, 4 decisions); and :data:`METER`, whose rates and updates read a numeric
input, with two ``at end`` clauses and bindings that read ``prev()`` of a condition and of the
speed, in the tiny scenario ``goal_ahead`` (no obstacle). Each plays 200 seeded random action
sequences, then one run to every value of every boolean input, location, label and ``at end``
guard that the engine's graph reaches and the random runs missed, and checks that together they
saw every such value. The last two also with `episode ends when` (a run ends where its sample's
inputs satisfy the condition, in the network as in the engine). The same automaton and bindings, over
a 2 s horizon, in rac.model.scenes' ``highway`` and ``overtaking``, in its ``t_junction`` under
CommonUppRoad's modelling choices (`dynamics increments`, `collision sticky`, `offroad_from`, `allow
when`), and on a straight road where edge cases meet (:func:`edge_case_source`: a late ego start,
speeds clamped at 0 and at ``max_speed``, headings past pi, trajectories that end mid-horizon, a goal
window). The random runs choose among the actions the engine allows; where `allow when` allows none,
the network must deadlock at the same decision (no choice of the Action enabled), which the highway
under a keep-away rule exercises. Two more tests: a changed label of
the emitted model makes the comparison fail (it is live), and a binding that reads ``prev(turn)``
and ``prev(jerk)`` reads the same value at the first sample whichever order UPPAAL takes the
committed edges at time 0 in. Last, test_agreement's random automata (several locations, rates reading a
real and an int input, rational and negative update coefficients, `at end`, `episode ends when`) with
bindings in ``avoidable_obstacle`` (:data:`RANDOM_BINDINGS`), a few runs each; and with bindings within
the inputs' ranges (:data:`IN_RANGE_BINDINGS`), the learning episodes (the batch runtime's rewards, what a
learner gets) along the product's runs.
"""

from __future__ import annotations

import ctypes
import dataclasses
import functools
import math
import re
import shutil
import subprocess
import tempfile
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

import fuzzgen
import numpy as np
import pytest
import utap as utap_module
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st
from lxml import etree
from test_agreement import automata
from tiny_scenarios import TINY_SCENARIOS, Block, GoalBox, StraightRoad, TinySettings

from rac import ir
from rac.compiler import compile_file
from rac.engine.budget import BudgetExceeded
from rac.engine.evaluate import EvaluationError
from rac.engine.explore import action_pairs
from rac.engine.product import ACCRUED, ENDED, READ, SAMPLED, MirrorArithmetic, ProductGraph, explore_product
from rac.ir.significands import Unrepresentable
from rac.learning.episodes import EpisodeBatch
from rac.model import ModelData, NativeModel
from rac.model.commonroad import EgoStart
from rac.model.data import ModelRangeError
from rac.model.program import CheckedProgram
from rac.model.scenes import write_scene
from rac.runtime.semantics import mirror_accrual, mirror_update
from rac.targets.uppaal.automaton import UppaalError
from rac.targets.uppaal.declarations import C_PRELUDE
from rac.targets.uppaal.model import generate_uppaal_model, model_vocabulary

COMPILER = shutil.which("cc") or shutil.which("gcc")
pytestmark = pytest.mark.skipif(COMPILER is None, reason="no C compiler (cc or gcc) on PATH")

REPO = Path(__file__).resolve().parents[2]
LEFT_TURN = REPO / "examples" / "left_turn"
DRIVING_RA = REPO / "stdlib" / "driving.ra"
RUNS = 200  #: random action sequences per scenario
EGO = ("x", "y", "v", "acc", "head", "jerk", "turn")
#: The template of the continuous ground truth (hybrid clocks under ODEs): only its location is
#: followed; its clocks are not integrated.
GROUND_TRUTH = "Dynamics"

#: The left turn's bindings (examples/left_turn/model.ra), for the tiny scenarios.
BINDINGS = ("isClose = mindist() < 3 * collision_distance",
            "prog    = dist_goal() < prev(dist_goal())",
            "comf    = fabs(acc) < comfort_acceleration * max_acceleration && fabs(turn) < comfort_turn * max_turn",
            "collide = collide()",
            "dgoal   = dist_goal()")

#: What driving.ra does not exercise: rates and updates that read a numeric input (the first
#: sample accrues on read?, the hybrid clock corrected), an update reading a reward updated
#: before it, a fractional update of a negative reward (`(7*iPen - 3*iDist) / 21`: C's division
#: truncates towards zero, Python's `//` floors), two `at end` clauses (conditional updates),
#: prev() of a condition and of the ego.
METER = """\
automaton Meter {{
    input near : bool
    input gain : bool
    input d    : real in [0, 1000]

    reward dist, pen
    objective dist + pen

    sample every 0.5
    horizon 4

    initial location Far {{ dist' == 2*d;    pen' == 0 }}
    location Near        {{ dist' == 20 - d; pen' == -1 }}

    edge Far -> Near when near && d < 29 do pen = pen - d, dist = dist + 3*pen
    edge Near -> Far when !near          do dist = dist - 2, pen = pen/3 - dist/7

    at end when gain do pen = pen + 10
    at end when d < 10 do dist = dist * 2

{block}}}
"""
METER_BINDINGS = ("near = acc > 0",
                  "gain = v > prev(v) || prev(acc > 0)",
                  "d    = dist_goal()")


# ---------------------------------------------------------------- UPPAAL declarations as C
def strip_comments(code: str) -> str:
    return re.sub(r"//[^\n]*", "", code)


def split_top(text: str, separator: str = ",") -> list[str]:
    """``text`` split at ``separator`` outside parentheses and brackets."""
    parts, depth, start, i = [], 0, 0, 0
    while i < len(text):
        ch = text[i]
        if ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        elif depth == 0 and text.startswith(separator, i):
            parts.append(text[start:i].strip())
            start = i + len(separator)
            i += len(separator)
            continue
        i += 1
    rest = text[start:].strip()
    return [*parts, rest] if rest or parts else []


def top_level(code: str) -> list[str]:
    """The top-level statements of declarations: variable declarations up to their ``;``, function
    definitions up to their closing brace (an initialiser's braces stay inside its declaration)."""
    statements, depth, start = [], 0, 0
    for i, ch in enumerate(code):
        if ch == "{":
            depth += 1
        elif ch == "}":
            depth -= 1
            head = code[start:i].split("{", 1)[0]
            if depth == 0 and "(" in head and "=" not in head:
                statements.append(code[start:i + 1].strip())
                start = i + 1
        elif ch == ";" and depth == 0:
            statements.append(code[start:i + 1].strip())
            start = i + 1
    assert not code[start:].strip(), code[start:]
    return [s for s in statements if s]


@dataclass(frozen=True)
class Variable:
    name: str  #: as written in the UPPAAL code
    kind: str  #: bool, int32_t, double, clock, hybrid; an array ``bool[9]`` (``allow when``'s ``ALLOWED``)


@dataclass
class Declarations:
    """What a declaration section declares: mutable variables, constants, functions, channels."""

    variables: list[Variable] = field(default_factory=list)
    constants: list[str] = field(default_factory=list)
    functions: list[str] = field(default_factory=list)
    channels: list[str] = field(default_factory=list)

    @property
    def names(self) -> list[str]:
        return [v.name for v in self.variables] + self.constants + self.functions


def declarations(code: str) -> Declarations:
    found = Declarations()
    for statement in top_level(strip_comments(code)):
        function = re.match(r"(\w+)\s+(\w+)\s*\(", statement)
        if function and statement.endswith("}"):
            found.functions.append(function.group(2))
            continue
        match = re.fullmatch(r"(const\s+)?(broadcast\s+chan|hybrid\s+clock|clock|bool|int32_t|double)\s+(.*);",
                             statement, re.S)
        assert match, f"a declaration this interpreter does not know: {statement!r}"
        const, kind, rest = match.groups()
        kind = " ".join(kind.split())
        for declarator in split_top(rest):
            name = re.match(r"(\w+)", declarator).group(1)
            if kind == "broadcast chan":
                found.channels.append(name)
            elif const:
                found.constants.append(name)
            else:
                kind = {"hybrid clock": "hybrid"}.get(kind, kind)
                size = re.match(r"\w+\s*\[\s*(\d+)\s*\]", declarator.split("=")[0].strip())
                found.variables.append(Variable(name, kind if size is None else f"{kind}[{size.group(1)}]"))
    return found


def as_c(code: str) -> str:
    """UPPAAL declarations as C: channels dropped, clocks and hybrid clocks as doubles."""
    lines = []
    for line in code.splitlines():
        if re.match(r"\s*(urgent\s+)?(broadcast\s+)?chan\b", line):
            continue
        lines.append(re.sub(r"^(\s*)(hybrid\s+)?clock\b", r"\1double", line))
    return "\n".join(lines)


CTYPES = {"bool": ctypes.c_bool, "int32_t": ctypes.c_int32, "double": ctypes.c_double, "clock": ctypes.c_double,
          "hybrid": ctypes.c_double}


def ctype(kind: str) -> type:
    """The ctypes type of a variable's kind (``bool[9]``: an array of 9 ``c_bool``)."""
    array = re.fullmatch(r"(\w+)\[(\d+)\]", kind)
    return CTYPES[kind] if array is None else CTYPES[array.group(1)] * int(array.group(2))


# ---------------------------------------------------------------- the network
@dataclass
class Edge:
    process: str
    index: int
    source: str
    target: str
    sync: str | None  #: ``accrue!``, ``sense?``, ... or None
    selects: list[tuple[str, str, str]]  #: (name, low, high) of each select variable
    guard: Callable[..., bool] | None
    assign: Callable[..., None] | None
    controllable: bool
    bounds: list[tuple[int, int]] = field(default_factory=list)  #: the selects' ranges, read from C


@dataclass
class Process:
    name: str
    template: str
    args: dict[str, int]
    init: str
    committed: set[str]
    rates: dict[str, list[tuple[str, Callable[[], float]]]]  #: per location: (clock symbol, rate)
    bounds: dict[str, list[tuple[str, Callable[[], float]]]]  #: per location: (clock symbol, upper bound)
    edges: dict[str, list[Edge]]  #: by source location


@dataclass(frozen=True)
class Move:
    sender: int
    edge: Edge
    binding: tuple[int, ...]
    receivers: tuple[tuple[int, Edge], ...]


State = tuple[tuple[str, ...], tuple[object, ...], int]  #: locations, variable values, decisions taken


class Network:
    """The emitted XML compiled as C (see the module docstring) and interpreted: locations in Python,
    every variable in the shared library. A state is ``(locations, variables, decisions taken)``;
    :meth:`instant` plays the transitions of one instant, :meth:`delay` lets time pass."""

    def __init__(self, xml: str, folder: Path):
        root = etree.fromstring(xml.encode("utf-8"))
        glob = root.findtext("declaration")
        self.globals = declarations(glob)
        self.channels = set(self.globals.channels)
        templates = {t.findtext("name"): t for t in root.findall("template")}
        system = strip_comments(root.findtext("system"))
        instances = {name: (template, [a.strip() for a in args.split(",") if a.strip()])
                     for name, template, args in re.findall(r"(\w+)\s*=\s*(\w+)\s*\(([^)]*)\)\s*;", system)}
        order = [p.strip() for p in re.search(r"\bsystem\s+([^;]*);", system).group(1).split(",")]
        source = [C_PRELUDE, as_c(glob)]
        self.symbols: list[tuple[str, str]] = [(v.name, v.kind) for v in self.globals.variables]
        pending: list[tuple[str, dict]] = []  # (process, description) until the library is loaded
        for name in order:
            template_name, args = instances.get(name, (name, []))
            template = templates[template_name]
            local_code = template.findtext("declaration") or ""
            local = declarations(local_code)
            assert not local.channels
            parameters = [re.fullmatch(r"(?:const\s+)?(\w+)\s+(\w+)", p.strip()).groups()
                          for p in split_top(template.findtext("parameter") or "")]
            assert len(parameters) == len(args), (name, parameters, args)
            renamed = [n for _, n in parameters] + local.names
            prefix = f"{name}__"
            source.append(f"/* ---- process {name} (template {template_name}) */")
            source += [f"#define {n} {prefix}{n}" for n in renamed]
            source += [f"const {t} {n} = {a};" for (t, n), a in zip(parameters, args)]
            source.append(as_c(local_code))
            self.symbols += [(prefix + v.name, v.kind) for v in local.variables]
            locals_ = set(renamed)
            description = {"template": template_name, "args": {n: int(a) for (_, n), a in zip(parameters, args)},
                           "locations": {}, "edges": []}
            ids = {}
            for loc in template.findall("location"):
                loc_name = loc.findtext("name")
                ids[loc.get("id")] = loc_name
                rates, bounds = [], []
                for j, part in enumerate(split_top(loc.findtext("label[@kind='invariant']") or "", "&&")):
                    rate = re.fullmatch(r"(\w+)'\s*==\s*(.+)", part, re.S)
                    bound = re.fullmatch(r"(\w+)\s*<=\s*(.+)", part, re.S)
                    assert rate or bound, f"an invariant this interpreter does not know: {part!r}"
                    clock, expr = (rate or bound).groups()
                    function = f"{prefix}{'r' if rate else 'b'}_{loc.get('id')}_{j}"
                    source.append(f"double {function}(void) {{ return {expr}; }}")
                    symbol = prefix + clock if clock in locals_ else clock
                    (rates if rate else bounds).append((symbol, function))
                description["locations"][loc_name] = (loc.find("committed") is not None, rates, bounds)
            description["init"] = ids[template.find("init").get("ref")]
            for n, t in enumerate(template.findall("transition")):
                labels = {label.get("kind"): label.text for label in t.findall("label")}
                selects = []
                for part in split_top(labels.get("select") or ""):
                    match = re.fullmatch(r"(\w+)\s*:\s*int\[([^,\]]+),([^\]]+)\]", part)
                    assert match, part
                    selects.append(match.groups())
                params = ", ".join(f"int32_t {s}" for s, _, _ in selects) or "void"
                functions = {}
                if labels.get("guard"):
                    functions["guard"] = f"{prefix}g{n}"
                    source.append(f"bool {prefix}g{n}({params}) {{ return {labels['guard']}; }}")
                if labels.get("assignment"):
                    functions["assign"] = f"{prefix}a{n}"
                    source.append(f"void {prefix}a{n}({params}) {{ {labels['assignment']}; }}")
                for k, (_, low, high) in enumerate(selects):
                    source.append(f"int32_t {prefix}s{n}_{k}_low(void) {{ return {low}; }}")
                    source.append(f"int32_t {prefix}s{n}_{k}_high(void) {{ return {high}; }}")
                sync = labels.get("synchronisation")
                if sync is not None:
                    assert sync[:-1] in self.channels and sync[-1] in "!?", sync
                description["edges"].append((n, ids[t.find("source").get("ref")], ids[t.find("target").get("ref")],
                                             sync, selects, functions, t.get("controllable") != "false"))
            source += [f"#undef {n}" for n in renamed]
            pending.append((name, description))
        self.source = "\n".join(source) + "\n"
        self.lib = self._compile(folder)
        self.variables = [(symbol, kind, ctype(kind).in_dll(self.lib, symbol)) for symbol, kind in self.symbols]
        self.values = {symbol: variable for symbol, _, variable in self.variables}
        self.processes = [self._process(name, description) for name, description in pending]
        self.index = {p.name: i for i, p in enumerate(self.processes)}
        self.start = self.snapshot()  # as the C initialisers set them, before any run

    def _compile(self, folder: Path) -> ctypes.CDLL:
        path = folder / "network.c"
        path.write_text(self.source, encoding="utf-8")
        library = folder / "network.so"
        # -Bsymbolic: the model's globals (`time`, ...) bind to the library's own, not to libc's;
        # -Wno-parentheses: `allow when a || b && c` is printed as UPPAAL reads it, as C does
        result = subprocess.run([COMPILER, "-O2", "-ffp-contract=off", "-fno-builtin", "-std=c99", "-Wall", "-Werror",
                                 "-Wno-unused-variable", "-Wno-parentheses", "-shared", "-fPIC", "-Wl,-Bsymbolic",
                                 "-o", str(library), str(path), "-lm"], capture_output=True, text=True, check=False)
        assert result.returncode == 0, result.stderr
        return ctypes.CDLL(str(library))

    def function(self, name: str, restype, nargs: int = 0) -> Callable:
        function = getattr(self.lib, name)
        function.restype = restype
        function.argtypes = [ctypes.c_int32] * nargs
        return function

    def _process(self, name: str, d: dict) -> Process:
        edges: dict[str, list[Edge]] = {loc: [] for loc in d["locations"]}
        for n, source, target, sync, selects, functions, controllable in d["edges"]:
            guard = self.function(functions["guard"], ctypes.c_bool, len(selects)) if "guard" in functions else None
            assign = self.function(functions["assign"], None, len(selects)) if "assign" in functions else None
            edge = Edge(name, n, source, target, sync, selects, guard, assign, controllable)
            edge.bounds = [(self.function(f"{name}__s{n}_{k}_low", ctypes.c_int32)(),
                            self.function(f"{name}__s{n}_{k}_high", ctypes.c_int32)()) for k in range(len(selects))]
            edges[source].append(edge)
        committed = {loc for loc, (c, _, _) in d["locations"].items() if c}
        rates = {loc: [(s, self.function(f, ctypes.c_double)) for s, f in r]
                 for loc, (_, r, _) in d["locations"].items()}
        bounds = {loc: [(s, self.function(f, ctypes.c_double)) for s, f in b]
                  for loc, (_, _, b) in d["locations"].items()}
        return Process(name, d["template"], d["args"], d["init"], committed, rates, bounds, edges)

    # ------------------------------------------------------------ states
    def value(self, symbol: str):
        return self.values[symbol].value

    def initial(self) -> State:
        """The initial state: every process in its initial location, the variables as initialised."""
        return tuple(p.init for p in self.processes), self.start, 0

    def snapshot(self) -> tuple[object, ...]:
        return tuple(tuple(variable) if "[" in kind else variable.value for _, kind, variable in self.variables)

    def restore(self, state: State) -> None:
        for (_, kind, variable), value in zip(self.variables, state[1]):
            if "[" in kind:
                variable[:] = value
            else:
                variable.value = value

    def describe(self, a: State, b: State) -> str:
        """How two states differ (locations and variables)."""
        lines = [f"{p.name}: {x} / {y}" for p, x, y in zip(self.processes, a[0], b[0]) if x != y]
        lines += [f"{symbol}: {x} / {y}" for (symbol, _, _), x, y in zip(self.variables, a[1], b[1]) if x != y]
        return "; ".join(lines)

    # ------------------------------------------------------------ transitions
    def moves(self, state: State, choices: list[tuple[int, ...]]) -> list[Move]:
        """Every transition enabled in ``state`` (restored): internal and sending edges with their
        receivers; guards read in ``state``. A controllable ``select`` takes its values from
        ``choices`` (one per firing, in order); any other select would be enumerated."""
        locations, _, taken = state
        committed = {i for i, p in enumerate(self.processes) if locations[i] in p.committed}
        found = []
        for i, process in enumerate(self.processes):
            for edge in process.edges[locations[i]]:
                if edge.sync is not None and edge.sync.endswith("?"):
                    continue
                if edge.selects and edge.controllable and taken == len(choices):
                    # the engine's run ends here (`allow when` leaves no action): the network must deadlock
                    allowed = [b for b in np.ndindex(*[hi - lo + 1 for lo, hi in edge.bounds])
                               if edge.guard is None or edge.guard(*(v + lo for v, (lo, _) in zip(b, edge.bounds)))]
                    assert not allowed, f"the emitted model allows {allowed} where the engine's run ends"
                    continue
                if edge.selects and edge.controllable:
                    bindings = [choices[taken]]
                    assert all(lo <= v <= hi for v, (lo, hi) in zip(bindings[0], edge.bounds)), bindings
                else:
                    bindings = [tuple(values) for values in np.ndindex(*[hi - lo + 1 for lo, hi in edge.bounds])]
                    bindings = [tuple(v + lo for v, (lo, _) in zip(b, edge.bounds)) for b in bindings]
                for binding in bindings:
                    if edge.guard is not None and not edge.guard(*binding):
                        continue
                    receivers = []
                    if edge.sync is not None:
                        wanted = edge.sync[:-1] + "?"
                        for j, other in enumerate(self.processes):
                            if j == i:
                                continue
                            enabled = [e for e in other.edges[locations[j]]
                                       if e.sync == wanted and (e.guard is None or e.guard())]
                            assert all(not e.selects for e in enabled)
                            assert len(enabled) <= 1, f"{other.name} has {len(enabled)} enabled edges on {wanted}"
                            if enabled:
                                receivers.append((j, enabled[0]))
                    if committed and i not in committed and not any(j in committed for j, _ in receivers):
                        continue
                    found.append(Move(i, edge, binding, tuple(receivers)))
        return found

    def fire(self, state: State, move: Move) -> State:
        """``move`` from ``state`` (restored): the sender's update, then the receivers' in order."""
        locations = list(state[0])
        if move.edge.assign is not None:
            move.edge.assign(*move.binding)
        locations[move.sender] = move.edge.target
        for j, edge in move.receivers:
            if edge.assign is not None:
                edge.assign()
            locations[j] = edge.target
        taken = state[2] + (1 if move.edge.selects and move.edge.controllable else 0)
        return tuple(locations), self.snapshot(), taken

    def check_invariants(self, state: State) -> None:
        """The clock bounds of every process's location hold (the library holds ``state``)."""
        for process, at in zip(self.processes, state[0]):
            for clock, bound in process.bounds[at]:
                assert self.value(clock) <= bound(), f"{process.name}.{at}: {clock} beyond its invariant"

    def delay(self, state: State) -> State:
        """Let time pass to the next deadline (the smallest upper bound of a clock invariant): clocks
        at rate 1, hybrid clocks at their location's rates, the ground truth's clocks left alone."""
        locations = state[0]
        step = math.inf
        for process, at in zip(self.processes, locations):
            for clock, bound in process.bounds[at]:
                step = min(step, bound() - self.value(clock))
        assert 0 < step < math.inf, f"no deadline to delay to ({step})"
        rates = {symbol: 1.0 for symbol, kind, _ in self.variables if kind in ("clock", "hybrid")}
        frozen = set()
        for process, at in zip(self.processes, locations):
            for clock, rate in process.rates[at]:
                if process.template == GROUND_TRUTH:
                    frozen.add(clock)
                else:
                    rates[clock] = rate()
        for symbol, rate in rates.items():
            if symbol not in frozen:
                self.values[symbol].value = self.value(symbol) + rate * step
        return locations, self.snapshot(), state[2]

    def instant(self, state: State, choices: list[tuple[int, ...]],
                observe: Callable[[State, Move, State], None]) -> State:
        """Every transition sequence from ``state`` up to the point where time must pass (every order
        of the committed processes); ``observe(before, move, after)`` sees each transition with the
        library in ``after``. All of them must end in one state, which is returned."""
        stack, seen, ends = [state], {state}, []
        while stack:
            current = stack.pop()
            self.restore(current)
            moves = self.moves(current, choices)
            if not moves:
                ends.append(current)
                continue
            if not any(at in p.committed for p, at in zip(self.processes, current[0])):
                deadline = min((bound() - self.value(clock) for p, at in zip(self.processes, current[0])
                                for clock, bound in p.bounds[at]), default=math.inf)
                assert deadline == 0, f"time may pass ({deadline}) while an edge is enabled: a race"
            for move in moves:
                self.restore(current)
                after = self.fire(current, move)
                observe(current, move, after)
                if after not in seen:
                    seen.add(after)
                    stack.append(after)
        assert ends, "no end to the instant"
        distinct = sorted(set(ends), key=repr)
        assert len(distinct) == 1, ("the order in which committed processes move changes the outcome: "
                                    + " | ".join(self.describe(distinct[0], other) for other in distinct[1:]))
        self.restore(distinct[0])
        return distinct[0]


# ---------------------------------------------------------------- the engine's side
def follow(graph: ProductGraph, state: int, action: int) -> int:
    found = [c for c in graph.choices(state) if int(graph.choice_action[c]) == action]
    assert len(found) == 1, (state, action)
    return int(graph.choice_target[found[0]])


def engine_path(graph: ProductGraph, decide_every: int, actions: list[int]) -> dict[tuple[int, int], int]:
    """The graph's node at each (sample, phase) along ``actions`` (one per decision sample), up to the
    run's end: the horizon, the sample `episode ends when` ends it at, or the decision at which
    `allow when` leaves no action (the actions run out there)."""
    node, nodes, decisions = graph.initial, {(0, SAMPLED): graph.initial}, iter(actions)
    for k in range(graph.horizon):
        if not graph.choices(node):
            assert k % decide_every == 0 and next(decisions, None) is None, (k, actions)
            break  # `allow when` allows no action here
        node = follow(graph, node, next(decisions) if k % decide_every == 0 else -1)
        assert (int(graph.k[node]), int(graph.phase[node])) == (k + 1, ACCRUED)
        nodes[(k + 1, ACCRUED)] = node
        node = follow(graph, node, -1)
        if graph.phase[node] == READ:
            nodes[(k + 1, READ)] = node
            node = follow(graph, node, -1)
        assert (int(graph.k[node]), int(graph.phase[node])) == (k + 1, SAMPLED)
        nodes[(k + 1, SAMPLED)] = node
        targets = graph.choice_target[graph.choices(node)]
        if targets.size == 0 or (targets.size == 1 and graph.phase[targets[0]] == ENDED):
            break  # the run ends here (`episode ends when`, or the horizon)
    if not graph.terminal()[node]:
        node = follow(graph, node, -1)
        assert int(graph.phase[node]) == ENDED
        nodes[(int(graph.k[node]), ENDED)] = node
    assert graph.terminal()[node]
    return nodes


def walk(graph: ProductGraph, node: int, rng: np.random.Generator) -> list[int]:
    """The actions of a random run on from ``node`` to its end, one uniformly among those the graph
    allows at each decision."""
    actions = []
    while choices := graph.choices(node):
        choice = choices[int(rng.integers(len(choices)))]
        if graph.choice_action[choice] >= 0:
            actions.append(int(graph.choice_action[choice]))
        node = int(graph.choice_target[choice])
    return actions


def decisions_to(graph: ProductGraph, node: int) -> list[int]:
    """The actions of a path from the start to ``node``."""
    counts = np.diff(graph.choice_offsets)
    sources = np.repeat(np.arange(graph.n_states), counts)
    targets, first = np.unique(graph.choice_target, return_index=True)
    parent = np.full(graph.n_states, -1)
    parent[targets] = sources[first]
    action = np.full(graph.n_states, -1)
    action[targets] = graph.choice_action[first]
    path = []
    while node != graph.initial:
        if action[node] >= 0:
            path.append(int(action[node]))
        node = int(parent[node])
        assert node >= 0
    return path[::-1]


@dataclass
class Scenario:
    automaton: ir.Automaton
    data: ModelData
    xml: str
    graph: ProductGraph


def validated(model: Any, folder: Path, name: str) -> str:
    """The emitted model's XML, validated with UPPAAL's parser (model and queries) when it is available
    (tests/support/utap.py; without it the comparison still runs)."""
    located = utap_module.locate()
    if located.path is not None:  # in a folder of its own: a test may build several models in one folder
        utap_module.Utap(located.path, Path(tempfile.mkdtemp(prefix="utap-", dir=folder))).validate(
            model.xml, model.queries, name)
    return model.xml


def build(source: Path, ends: ir.Guard | None = None) -> Scenario:
    """The file's scenario; ``ends``: its automaton with `episode ends when` that condition."""
    result = compile_file(source)
    automaton = dataclasses.replace(result.raise_for_errors(), episode_ends=ends)
    data = result.model_data
    xml = validated(generate_uppaal_model(automaton, data=data), source.parent, source.stem)
    return Scenario(automaton, data, xml, explore_product(data, automaton))


def truncates(automaton: ir.Automaton, scale: int) -> bool:
    """Whether a mirror of ``automaton`` at ``scale`` may be truncated (then it drifts from reward * scale):
    a fractional coefficient of an accrual or an update, or an update's fractional constant (`r = r + 1/3`
    is `iR = (3*iR + 10000) / 3`), which was left out."""
    accruals = [mirror_accrual(rate, automaton.period, scale) for loc in automaton.locations for rate in loc.rates]
    updates = [mirror_update(u.value, scale)
               for e in [*automaton.all_edges(), *automaton.end_clauses] for u in e.updates]
    return any(c.denominator != 1 for _, terms in [*accruals, *updates] for c, _ in terms) \
        or any(const.denominator != 1 for const, _ in updates)


# ---------------------------------------------------------------- one scenario
class Comparison:
    """The emitted network and the engine, compared along action sequences."""

    def __init__(self, scenario: Scenario, folder: Path):
        self.s = scenario
        self.net = Network(scenario.xml, folder)
        a, data = scenario.automaton, scenario.data
        self.names = model_vocabulary(a, data=data)
        self.automaton_process = self.net.index[self.names.process]
        self.locations = {self.names.locations[name]: name for name in a.location_names}
        self.native = NativeModel(data)
        lib = self.net.lib
        self.labels = {name: self.net.function(name, ctypes.c_bool) for name in ("collide", "offroad", "goal")}
        self.obs_x = self.net.function("obs_x", ctypes.c_double, 1)
        self.obs_y = self.net.function("obs_y", ctypes.c_double, 1)
        jerks = list((ctypes.c_int32 * data.action("jerk").count).in_dll(lib, "JERK_VALUES"))
        turns = list((ctypes.c_int32 * data.action("turn").count).in_dll(lib, "TURN_VALUES"))
        self.jerks, self.turns = jerks, turns
        pairs = action_pairs(data)
        self.action_of = {(int(j), int(t)): a for a, (j, t) in enumerate(pairs)}
        self.pair_of = {a: (jerks.index(int(j)), turns.index(int(t))) for a, (j, t) in enumerate(pairs)}
        self.obstacles = [p for p in self.net.processes if f"{p.name}__ox" in self.net.values]
        assert len(self.obstacles) == data.obstacle_count
        assert ctypes.c_int32.in_dll(lib, "STEPS").value == scenario.graph.horizon
        self.decide_every = ctypes.c_int32.in_dll(lib, "DECIDE_EVERY").value
        assert self.decide_every == data.decide_every
        g = scenario.graph
        self.settled, self.inputs, self.mirrors = g.settled, g.inputs, g.mirrors
        #: what the runs should see every reachable value of, by phase: after the edge the boolean
        #: inputs, the location and the labels; after `at end` the guard of each clause
        self.conditions = {(SAMPLED, "location"): g.location,
                           **{(SAMPLED, i.name): self.inputs[i.name] for i in a.inputs if i.is_bool},
                           **{(SAMPLED, label): g.labels[label] for label in ("collide", "offroad", "goal")}}
        if a.end_clauses:
            # (an automaton without inputs holds none: one empty column set per state)
            held = np.column_stack([self.inputs[i.name] for i in a.inputs]).astype(np.int64) if a.inputs \
                else np.zeros((g.n_states, 0), dtype=np.int64)
            arithmetic = MirrorArithmetic(a, data.scale)
            for i, clause in enumerate(a.end_clauses):
                self.conditions[(ENDED, f"at end #{i + 1}")] = arithmetic.guard(clause.guard, held)
        self.covered: set[tuple[int, str, int]] = set()
        self.samples = 0
        self.stuck_runs = 0  #: runs that ended where `allow when` left no action
        #: whether a mirror may truncate (then its hybrid clock drifts by up to a unit per sample)
        self.truncates = truncates(a, data.scale)

    # ------------------------------------------------------------ reading the network
    def network_state(self, state: State) -> dict[str, object]:
        """The network's discrete state (the library holds ``state``), in the engine's terms."""
        a, v = self.s.automaton, self.net.value
        state = {"k": v("count"), "ego": tuple(v(c) for c in EGO), "settled": bool(v(self.names.settled)),
                 "location": self.locations[state[0][self.automaton_process]]}
        for item in a.inputs:
            symbol = self.names.bools[item.name] if item.is_bool else self.names.significands[item.name]
            state[item.name] = int(v(symbol))
        for reward in a.rewards:
            state[f"mirror:{reward}"] = v(self.names.mirrors[reward])
        return state

    def engine_state(self, node: int) -> dict[str, object]:
        g, a = self.s.graph, self.s.automaton
        state = {"k": int(g.k[node]), "ego": tuple(int(e) for e in g.ego[node]), "settled": bool(self.settled[node]),
                 "location": a.location_names[int(g.location[node])]}
        for item in a.inputs:
            state[item.name] = int(self.inputs[item.name][node])
        for reward in a.rewards:
            state[f"mirror:{reward}"] = int(self.mirrors[reward][node])
        return state

    def cover(self, node: int) -> None:
        phase = int(self.s.graph.phase[node])
        self.covered |= {(p, name, int(column[node])) for (p, name), column in self.conditions.items() if p == phase}

    def check_labels(self, node: int, where: str) -> None:
        g = self.s.graph
        ours = {name: bool(f()) for name, f in self.labels.items()}
        theirs = {name: bool(g.labels[name][node]) for name in self.labels}
        assert ours == theirs, f"{where}: labels {ours} in the emitted model, {theirs} in the engine"

    def check_rewards(self, where: str) -> None:
        """The hybrid clocks follow their mirrors (a significand unit of truncation per sample at most)."""
        scale = self.s.data.scale
        tolerance = (self.samples + 1) / scale if self.truncates else 1e-9
        for reward in self.s.automaton.rewards:
            hybrid, mirror = self.net.value(self.names.hybrids[reward]), self.net.value(self.names.mirrors[reward])
            assert abs(hybrid - mirror / scale) <= tolerance + 1e-9 * abs(hybrid), (where, reward, hybrid, mirror)

    def check_obstacles(self, k: int, where: str) -> None:
        for p in self.obstacles:
            i = p.args["i"]
            ours = (self.net.value(f"{p.name}__ox"), self.net.value(f"{p.name}__oy"))
            assert ours == (self.obs_x(i), self.obs_y(i)), where
            native = self.native.obstacle_position(i, k)
            assert ours == ((0.0, 0.0) if native is None else native[:2]), (where, p.name, ours, native)

    def check_obstacle_flow(self, k: int, where: str) -> None:
        """Just before sample ``k + 1``: each obstacle that moves on in a straight line (same waypoint
        speed and heading at ``k`` and ``k + 1``) has flowed to its position at ``k + 1``: within two
        significand units (the waypoints' positions are truncated), and the sideways drift of a heading
        truncated by up to one unit (pi held as 3.1415 at exponent 4 drifts by v * C1 * 0.0000927 a period;
        the waypoints keep the positions exact)."""
        data = self.s.data
        for p in self.obstacles:
            i = p.args["i"]
            now, then = self.native.waypoint(i, k), self.native.waypoint(i, k + 1)
            if now < 0 or then < 0 or (data.wp_vel[now], data.wp_head[now]) != (data.wp_vel[then], data.wp_head[then]):
                continue
            x, y, _ = self.native.obstacle_position(i, k + 1)
            ours = (self.net.value(f"{p.name}__ox"), self.net.value(f"{p.name}__oy"))
            tolerance = 2 / data.scale + data.wp_vel[now] / data.scale * data.period / data.scale
            assert ours == pytest.approx((x, y), abs=tolerance), (where, p.name, ours, (x, y))

    # ------------------------------------------------------------ one run
    def run(self, actions: list[int]) -> None:
        """Play the action sequence (engine action indices, one per decision) on the network and the graph."""
        g, a = self.s.graph, self.s.automaton
        nodes = engine_path(g, self.decide_every, actions)
        choices = [self.pair_of[action] for action in actions]
        net = self.net
        assert net.channels == {"accrue", "read", "sense", "decide", "finish"}
        finished = []
        self.samples = 0

        def compare(state: State, node: int, where: str, **override: object) -> None:
            ours, theirs = self.network_state(state), self.engine_state(node)
            theirs.update(override)
            differ = {key: (ours[key], theirs[key]) for key in theirs if ours[key] != theirs[key]}
            assert not differ, f"{where} (actions {actions}): emitted model / engine differ in {differ}"

        def observe(before: State, move: Move, after: State) -> None:
            sync = move.edge.sync
            k = net.value("count")
            where = f"sample {k}, after {move.edge.process}'s {sync or 'edge'}"
            net.check_invariants(after)
            if move.edge.selects and move.edge.controllable:
                pair = (self.jerks[move.binding[0]], self.turns[move.binding[1]])
                assert (net.value("jerk"), net.value("turn")) == pair, where
                assert self.action_of[pair] == actions[before[2]], where
            elif sync == "accrue!":
                node = nodes[(k, ACCRUED)]
                compare(after, node, where)
                self.check_labels(node, where)
                self.check_obstacles(k, where)
            elif sync == "read!":
                if (k, READ) in nodes:
                    compare(after, nodes[(k, READ)], where)
                else:  # the new inputs, not yet reacted to: the engine shows them only after the edge
                    fresh = self.engine_state(nodes[(k, SAMPLED)])
                    compare(after, nodes[(k, ACCRUED)], where, settled=False,
                            **{item.name: fresh[item.name] for item in a.inputs})
            elif sync == "sense!":
                node = nodes[(k, SAMPLED)]
                compare(after, node, where)
                self.check_labels(node, where)
                self.samples = k
                self.check_rewards(where)
                self.cover(node)
            elif sync == "finish!":
                node = nodes.get((k, ENDED), nodes[(k, SAMPLED)])
                compare(after, node, where)
                self.cover(node)
                finished.append(k)

        state = net.initial()
        net.restore(state)
        stuck = False
        for _ in range(10 * (g.horizon + 2)):
            state = net.instant(state, choices, observe)
            k = net.value("count")
            if k == 0:  # the start: the engine's first state, with the first decision's actions already set
                start = nodes[(0, SAMPLED)]
                chosen = (self.jerks[choices[0][0]], self.turns[choices[0][1]]) if choices else (0, 0)
                compare(state, start, "the start", ego=(*self.engine_state(start)["ego"][:5], *chosen))
                self.check_labels(start, "the start")
                self.check_obstacles(0, "the start")
                self.cover(start)
            if finished:
                break
            if any(at in p.committed for p, at in zip(net.processes, state[0])):
                stuck = True  # a committed process cannot move: `allow when` left the Action no choice
                break
            state = net.delay(state)
            self.check_obstacle_flow(k, f"before sample {k + 1}")
        else:
            raise AssertionError("the run did not finish")
        end = max(k for k, _ in nodes)  # the horizon, or the sample the automaton ended the run at
        if stuck:  # the engine's run ends at the same decision, without `at end`
            self.stuck_runs += 1
            assert (net.value("count"), state[2], finished) == (end, len(actions), []), (actions, end, finished)
            assert (end, ENDED) not in nodes and not g.choices(nodes[(end, SAMPLED)]), actions
        else:
            assert finished == [end] and state[2] == -(-end // self.decide_every)
        if a.episode_ends is not None and not stuck:  # after the end the hybrid clocks stop: their rates are 0
            state = net.delay(state)
            self.check_rewards(f"{net.value('count')} samples, one period after the end")
        assert [p.name for p in net.processes if p.template == GROUND_TRUTH] == [GROUND_TRUTH]
        assert state[0][net.index[GROUND_TRUTH]] != net.processes[net.index[GROUND_TRUTH]].init

    def run_many(self, seed: int, runs: int = RUNS) -> int:
        """``runs`` random action sequences (uniform among the allowed actions at each decision), then
        one run to each value of a condition that the graph reaches and the random runs missed; returns
        how many runs were played."""
        g = self.s.graph
        rng = np.random.default_rng(seed)
        played = 0
        for _ in range(runs):
            self.run(walk(g, g.initial, rng))
            played += 1
        reachable: dict[tuple[int, str, int], int] = {}  # each value of each condition: its first node
        for (phase, name), column in self.conditions.items():
            where = np.flatnonzero(g.phase == phase)
            values, first = np.unique(column[where], return_index=True)
            reachable.update({(phase, name, int(value)): int(where[i]) for value, i in zip(values, first)})
        for condition, node in sorted(reachable.items()):
            if condition in self.covered:
                continue
            path = decisions_to(g, node) + walk(g, node, rng)
            self.run(path)
            played += 1
        assert self.covered == set(reachable), set(reachable) - self.covered
        return played


# ---------------------------------------------------------------- scenarios
def left_turn_source(folder: Path) -> Path:
    """examples/left_turn/model.ra with a 1 s horizon (10 samples) and a coarse action grid."""
    text = (LEFT_TURN / "model.ra").read_text(encoding="utf-8")
    scenario = (LEFT_TURN / "left_turn.xml").as_posix()
    coarse = (f'scenario "{scenario}"\n'
              "        action jerk in [-2, 2] step 2\n"
              "        action turn in [-0.4, 0.4] step 0.4")
    assert 'scenario "left_turn.xml"' in text and "horizon 10 " in text
    text = text.replace('scenario "left_turn.xml"', coarse).replace("horizon 10 ", "horizon 1 ")
    path = folder / "left_turn.ra"
    path.write_text(text, encoding="utf-8")
    return path


def tiny_block(folder: Path, name: str, bindings: tuple[str, ...], choices: tuple[str, ...] = ()) -> str:
    """The model block of the tiny scenario ``name`` (written into ``folder``) with ``bindings`` and the
    modelling choices ``choices`` (lines of the block)."""
    tiny = TINY_SCENARIOS[name]()
    tiny.write(folder)
    block = tiny.settings.model_block(f"{tiny.name}.xml", bindings)
    block = block[:block.rindex("}")] + "".join(f"    {line}\n" for line in choices) + "}\n"
    return "".join(f"    {line}\n" for line in block.splitlines())


def tiny_driving_source(folder: Path, name: str) -> Path:
    """stdlib/driving.ra's automaton in a tiny scenario, as tests/targets/test_utap.py builds it."""
    tiny = TINY_SCENARIOS[name]()
    tiny.write(folder)
    return driving_source(folder, name, tiny.settings)


def driving_source(folder: Path, name: str, settings: TinySettings, choices: tuple[str, ...] = ()) -> Path:
    """stdlib/driving.ra's automaton with the left turn's bindings in the scene ``folder/NAME.xml``
    under ``settings``, with the modelling choices ``choices`` (lines of the model block)."""
    text = DRIVING_RA.read_text(encoding="utf-8")
    text = text[:text.index("    query ")]
    text = text.replace("sample every 0.1", f"sample every {float(settings.sense_period):g}")
    text = text.replace("horizon 30", f"horizon {float(settings.horizon):g}")
    block = settings.model_block(f"{name}.xml", BINDINGS)
    block = block[:block.rindex("}")] + "".join(f"    {line}\n" for line in choices) + "}\n"
    text += "\n" + "".join(f"    {line}\n" for line in block.splitlines()) + "}\n"
    path = folder / f"{name}.ra"
    path.write_text(text, encoding="utf-8")
    return path


#: The generated scenes' settings: a 2 s horizon (4 samples, 2 decisions), speeds up to 30 m/s.
SCENE_SETTINGS = TinySettings(max_speed=Fraction(30), horizon=Fraction(2))
#: CommonUppRoad's modelling choices (docs/language.md, "Modelling choices").
CHOICES = ("dynamics increments", "collision sticky", "offroad_from 1",
           "allow when turn == 0 || (fabs(head) <= 0.2 && !offroad())")


def scene_source(folder: Path, scene: str, choices: tuple[str, ...] = ()) -> Path:
    """The driving automaton in rac.model.scenes' ``scene`` (highway, t_junction, ...)."""
    write_scene(scene, folder / f"{scene}.xml")
    return driving_source(folder, scene, SCENE_SETTINGS, choices)


def edge_case_source(folder: Path) -> Path:
    """A straight two-lane road on which the edge cases meet within a 2 s horizon: the ego starts
    late (0.4 s into the scenario, so the sample grid is not the scenario's), slowly and braking, so
    that its speed clamps at 0 under the harder braking, and at ``max_speed`` 3 under jerk +2; a car
    comes the other way with the heading 3.141593 (just past pi, as written with 6 decimals), and
    both dynamic obstacles' trajectories end at 1.5 s, mid-horizon; a parked van stands at an angle
    of -3.1 rad; the goal window [0.8, 1.6] s holds only samples 1 and 2."""
    road = StraightRoad(120.0, EgoStart(12.0, 1.75, 0.0, 1.0, -1.0), GoalBox(12.0, 20.0, 0.8, 1.6),
                        lanes=2, steps=15,
                        obstacles=(Block(11, x=30.0, y=5.25, velocity=6.0, heading=math.pi),
                                   Block(12, x=16.0, y=1.2, velocity=1.5, heading=0.05),
                                   Block(13, x=26.0, y=2.0, length=5.0, width=2.0, heading=-3.1)))
    # CommonRoad's schema wants the planning problem at step 0: the late start is written in afterwards,
    # as tiny_scenarios.late_start does
    text, made = re.subn(r"(<planningProblem .*?<initialState>.*?<time>\s*<exact>)0(</exact>)", r"\g<1>4\2",
                         road.xml("edges").decode("utf-8"), count=1, flags=re.S)
    assert made == 1
    (folder / "edges.xml").write_text(text, encoding="utf-8")
    return driving_source(folder, "edges", dataclasses.replace(SCENE_SETTINGS, max_speed=Fraction(3)))


def meter_source(folder: Path, bindings: tuple[str, ...] = METER_BINDINGS, scene: str = "goal_ahead",
                 choices: tuple[str, ...] = ()) -> Path:
    """:data:`METER` in the tiny scenario ``scene`` (default ``goal_ahead``)."""
    path = folder / "meter.ra"
    path.write_text(METER.format(block=tiny_block(folder, scene, bindings, choices)), encoding="utf-8")
    return path


SOURCES = {"left_turn": left_turn_source,
           "avoidable_obstacle": lambda folder: tiny_driving_source(folder, "avoidable_obstacle"),
           "meter_goal_ahead": meter_source,
           "highway": lambda folder: scene_source(folder, "highway"),
           "overtaking": lambda folder: scene_source(folder, "overtaking"),
           "t_junction_choices": lambda folder: scene_source(folder, "t_junction", CHOICES),
           "edge_cases": edge_case_source}
#: `episode ends when`: the driving automaton's run ends at an uncomfortable sample or near the goal (its
#: end clause), the meter's where `gain` holds (its first end clause applies there).
ENDS = {"avoidable_obstacle": ir.BOr((ir.BNot(ir.BInput("comf")), ir.BAtom("dgoal", "<", Fraction(2)))),
        "meter_goal_ahead": ir.BInput("gain")}


# ---------------------------------------------------------------- tests
@pytest.mark.parametrize("name", sorted(SOURCES))
def test_the_emitted_network_runs_like_the_engine(name: str, tmp_path: Path) -> None:
    comparison = Comparison(build(SOURCES[name](tmp_path)), tmp_path)
    assert comparison.run_many(seed=11) >= RUNS


@pytest.mark.parametrize("name", sorted(ENDS))
def test_a_run_ends_where_the_automaton_ends_it(name: str, tmp_path: Path) -> None:
    """`episode ends when`: the emitted Timer ends the run (finish!, the end clauses on that sample's inputs,
    no later sample, the hybrid clocks stopped) exactly where the engine's product does."""
    scenario = build(SOURCES[name](tmp_path), ENDS[name])
    ended = scenario.graph.phase == ENDED
    assert (ended & (scenario.graph.k < scenario.graph.horizon)).any()  # some runs end before the horizon
    comparison = Comparison(scenario, tmp_path)
    assert comparison.run_many(seed=13) >= RUNS


@pytest.mark.parametrize(("label", "changed"), [
    ("iPen = iPen - 50", "iPen = iPen - 51"),  # Near's accrual
    ("count == 1", "count == 2"),  # the first sample's accrual on read? comes a sample late
])
def test_the_comparison_notices_a_changed_label(label: str, changed: str, tmp_path: Path) -> None:
    """The interpreter and the comparisons are live: one changed label of the emitted model fails them."""
    scenario = build(meter_source(tmp_path))
    assert scenario.xml.count(label) >= 1
    scenario.xml = scenario.xml.replace(label, changed)
    with pytest.raises(AssertionError, match="emitted model / engine differ in {'mirror:"):
        Comparison(scenario, tmp_path).run_many(seed=3, runs=5)


def test_a_mirror_truncated_only_by_an_updates_constant_is_compared_as_truncated(tmp_path: Path) -> None:
    """`pen = pen - d + 1/3` is `iPen = (3*iPen - 3*d + 100) / 3` at exponent 2 (truncated towards zero, as the
    engine computes it): the comparison took a mirror as exact unless a coefficient was fractional, and
    failed this model, which runs alike in the network and the product, on its hybrid clock (a third of a
    unit off)."""
    path = meter_source(tmp_path)
    text = path.read_text(encoding="utf-8").replace("pen = pen/3 - dist/7", "pen = pen - dist")
    text = text.replace("near && d < 29 do pen = pen - d,", "near do pen = pen - d + 1/3,")  # d < 29: never here
    text = text.replace("dist' == 20 - d;", "dist' == 20 - 2*d;")  # d/2 per sample: a fractional coefficient
    path.write_text(text, encoding="utf-8")
    scenario = build(path)
    assert "(3*iPen - 3*d + 100) / 3" in scenario.xml
    assert truncates(scenario.automaton, scenario.data.scale)
    assert Comparison(scenario, tmp_path).run_many(seed=3, runs=10) >= 10


#: An automaton that reads nothing (tests/targets/test_emitted_alone.py runs it alone): its edges fire every
#: sample, an update reads a reward, `at end` applies unconditionally; ``{block}``: a model block, or nothing.
CLOCKWORK = """\
automaton Clockwork {{
    reward up, down
    objective up - down
    sample every 0.5
    horizon 3
    initial location Tick {{ up' == 1;  down' == 0 }}
    location Tock         {{ up' == 0;  down' == 2 }}
    edge Tick -> Tock do down = down + up / 3
    edge Tock -> Tick do up = up - 1
    at end do up = 2 * up
{block}}}
"""


def test_an_automaton_without_inputs_runs_alike_in_the_emitted_network_and_the_product(tmp_path: Path) -> None:
    """A model whose automaton reads no input (no binding): the comparison stacked the held inputs for the
    `at end` guards and failed on none (numpy: need at least one array), so no such model was compared."""
    path = tmp_path / "clockwork.ra"
    path.write_text(CLOCKWORK.format(block=tiny_block(tmp_path, "goal_ahead", ())), encoding="utf-8")
    scenario = build(path)
    assert scenario.automaton.inputs == ()
    assert Comparison(scenario, tmp_path).run_many(seed=2, runs=8) >= 8


@pytest.mark.parametrize(("base", "exponent"), [(2, 6), (16, 3)])
def test_other_bases_run_alike_in_the_emitted_network_and_the_product(base: int, exponent: int,
                                                                      tmp_path: Path) -> None:
    """A `model` block's base other than 10 (every whole model compared so far had base 10): the Meter at
    base 2 (64 units) and 16 (4096), its turn step 0.25 (whole significands there)."""
    path = meter_source(tmp_path)
    text = re.sub(r"base \d+", f"base {base}", path.read_text(encoding="utf-8"))
    text = re.sub(r"exponent \d+", f"exponent {exponent}", text)
    path.write_text(re.sub(r"action turn in \[[^\]]*\] step [0-9.]+", "action turn in [-0.25, 0.25] step 0.25", text),
                    encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # W0725: settings truncated to whole significands at this base
        scenario = build(path)
    assert scenario.data.scale == base ** exponent
    assert Comparison(scenario, tmp_path).run_many(seed=4, runs=20) >= 20


def test_prev_of_an_action_reads_the_same_start_in_every_order(tmp_path: Path) -> None:
    """``prev(turn)`` and ``prev(jerk)`` at the first sample. At time 0 the Controller's initial edge
    (``keep_sample()``, which keeps jerk and turn when a binding reads their ``prev``) and the
    Action's first choice are both in committed locations, so UPPAAL may take them in either
    order; the engine reads the start's actions (0) as ``prev`` at the first sample. Every order
    must give the same state."""
    bindings = ("near = acc > 0", "gain = turn != prev(turn) || jerk != prev(jerk)", "d    = dist_goal()")
    Comparison(build(meter_source(tmp_path, bindings)), tmp_path).run_many(seed=5, runs=20)


#: `allow when` that leaves no action in some states of the highway scene (a car within 6 m one period on).
KEEP_AWAY = "allow when mindist() > 6 && !offroad()"


def test_where_allow_when_leaves_no_action_both_end_the_run(tmp_path: Path) -> None:
    """Where `allow when` allows no action, rac's product ends the run (a sampled state without
    successors) and the emitted model deadlocks: the Action's committed location has no enabled
    choice. The runs that end so end at the same decision in both, without `at end`."""
    scenario = build(scene_source(tmp_path, "highway", (KEEP_AWAY,)))
    g = scenario.graph
    ends = (np.diff(g.choice_offsets) == 0) & (g.phase == SAMPLED) & (g.k < g.horizon)
    assert ends.any()
    comparison = Comparison(scenario, tmp_path)
    assert comparison.run_many(seed=17, runs=60) >= 60
    assert comparison.stuck_runs > 0


def test_the_comparison_notices_a_choice_allowed_where_the_run_ends(tmp_path: Path) -> None:
    """The deadlock check is live: an emitted `allow when` that allows every action fails it."""
    scenario = build(scene_source(tmp_path, "highway", (KEEP_AWAY,)))
    condition = "ALLOWED[j * TURN_COUNT + u] = mindist() &gt; 6.0 &amp;&amp; !offroad();"
    assert scenario.xml.count(condition) == 1
    scenario.xml = scenario.xml.replace(condition, "ALLOWED[j * TURN_COUNT + u] = true;")
    with pytest.raises(AssertionError, match="the emitted model allows"):
        Comparison(scenario, tmp_path).run_many(seed=17, runs=60)


def test_prev_of_a_sticky_collision_reads_the_previous_sample(tmp_path: Path) -> None:
    """`collision sticky` and a binding that reads ``prev(collide())``: the emitted read_inputs() ran
    after keep_collision() had set `crashed` for the current sample and evaluated the previous
    sample's collide() with it, so at the first colliding sample it read true where the previous
    sample did not collide (and the engine reads false). It now keeps `crashed` with the previous
    sample's state."""
    bindings = ("near = acc > 0", "gain = prev(collide())", "d    = dist_goal()")
    scenario = build(meter_source(tmp_path, bindings, "avoidable_obstacle", ("collision sticky",)))
    g = scenario.graph
    first = np.flatnonzero((g.phase == SAMPLED) & g.labels["collide"] & (scenario.graph.inputs["gain"] == 0))
    assert first.size  # samples at which the run collides for the first time
    comparison = Comparison(scenario, tmp_path)
    rng = np.random.default_rng(19)
    for node in first[:20]:
        comparison.run(decisions_to(g, int(node)) + walk(g, int(node), rng))
    assert comparison.run_many(seed=19, runs=20) >= 20


# ---------------------------------------------------------------- random automata in a scenario
#: Bindings for test_agreement's random automata (inputs b, c: bool; x: real in [-5, 5]; m: int in
#: [0, 3]): values that vary along the runs of the tiny scenario avoidable_obstacle, numbers beyond
#: their declared ranges now and then (bindings are not clipped) and not whole for the int input.
#: `m` is an `int` bound to numbers that are not whole, on purpose (`rac check` warns, W0726): the emitted
#: network and the product must read the same significands between whole numbers.
RANDOM_BINDINGS = ("b = acc > 0 || collide()",
                   "c = v > prev(v) || goal()",
                   "x = fmax(-6, fmin(6, dist_goal() / 4 - 5))",
                   "m = fmin(3.5, v / 2)")
RANDOM_HEAD = """\
automaton Random {{
    input b : bool
    input c : bool
    input x : real in [-5, 5]
    input m : int in [0, 3]
    reward r0
    objective r0
    sample every 0.5
    horizon {horizon}
    initial location L0 {{ r0' == 1 }}
    edge L0 -> L0 when b && c && x < 0 && m > 1
{block}}}
"""


@functools.cache
def random_base(folder: Path, horizon: int, bindings: tuple[str, ...] = RANDOM_BINDINGS
                ) -> tuple[ir.Automaton, ModelData]:
    """The model block every random automaton is put into (its inputs as test_agreement's)."""
    text = RANDOM_HEAD.format(horizon=horizon, block=tiny_block(folder, "avoidable_obstacle", bindings))
    path = folder / "random.ra"
    path.write_text(text, encoding="utf-8")
    result = compile_file(path)
    automaton = result.raise_for_errors()
    assert result.model_data is not None
    return automaton, result.model_data


class RandomComparison(Comparison):
    """:class:`Comparison` for automata whose updates may scale a reward by more than 1 (``r = 8/3 * r``):
    there a mirror's truncation grows with the reward, so its hybrid clock may drift from it by more
    than a unit per sample (as documented); the mirrors are still compared with the engine's exactly."""

    def __init__(self, scenario: Scenario, folder: Path):
        super().__init__(scenario, folder)
        a = scenario.automaton
        self.amplifies = any(sum(abs(c) for name, c in u.value.terms if name in a.rewards) > 1
                             for e in [*a.all_edges(), *a.end_clauses] for u in e.updates)

    def check_rewards(self, where: str) -> None:
        if not (self.amplifies and self.truncates):
            super().check_rewards(where)


@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large])
@given(random=automata(), horizon=st.sampled_from([2, 3]), seed=st.integers(0, 2**16))
def test_random_automata_run_alike_in_the_emitted_network_and_the_product(
        random: ir.Automaton, horizon: int, seed: int, tmp_path_factory: pytest.TempPathFactory) -> None:
    """test_agreement's random automata (rates reading inputs, rational and negative update coefficients,
    several locations, `at end`, `episode ends when`) with bindings in the tiny scenario avoidable_obstacle:
    the emitted network and the engine's product along random action sequences, as above."""
    folder = tmp_path_factory.getbasetemp() / "random-network"  # the session's (hypothesis runs many examples)
    folder.mkdir(exist_ok=True)
    base, data = random_base(folder, horizon)
    automaton = dataclasses.replace(random, name=base.name, inputs=base.inputs, model=base.model, period=base.period,
                                    horizon=base.horizon, queries=(), standard_queries=(), priority=random.rewards)
    try:
        model = generate_uppaal_model(automaton, data=data)
        graph = explore_product(data, automaton)
    except (UppaalError, Unrepresentable, EvaluationError, ModelRangeError):
        assume(False)  # E0801, two edges enabled where the bindings break `assume`, a mirror beyond int32
        return
    xml = validated(model, folder, "random")
    with tempfile.TemporaryDirectory(dir=folder) as case:
        assert RandomComparison(Scenario(automaton, data, xml, graph), Path(case)).run_many(seed, runs=6) >= 6


#: :data:`RANDOM_BINDINGS` kept within the inputs' declared ranges (whole for the int input): there the
#: learning episodes (rac.learning.episodes, on the Python runtime's floats) clip nothing, so they must
#: follow the product's runs exactly.
IN_RANGE_BINDINGS = ("b = acc > 0 || collide()",
                     "c = v > prev(v) || goal()",
                     "x = fmax(-5, fmin(5, dist_goal() / 4 - 5))",
                     "m = 2")


@settings(max_examples=15, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large])
@given(random=automata(), seed=st.integers(0, 2**16))
def test_random_automata_learn_on_the_products_runs(random: ir.Automaton, seed: int,
                                                    tmp_path_factory: pytest.TempPathFactory) -> None:
    """The learning episodes (:class:`rac.learning.episodes.EpisodeBatch`: the batch runtime, the reward a
    learner gets) along random action sequences against the product (rac verify's, the emitted model's
    integer arithmetic): the same location at every decision, the rewards equal to the mirrors over the
    scale (where no mirror truncates), and the run's end at the same sample."""
    folder = tmp_path_factory.getbasetemp() / "random-episodes"
    folder.mkdir(exist_ok=True)
    base, data = random_base(folder, 2, IN_RANGE_BINDINGS)
    automaton = dataclasses.replace(random, name=base.name, inputs=base.inputs, model=base.model, period=base.period,
                                    horizon=base.horizon, queries=(), standard_queries=(), priority=random.rewards,
                                    assumptions=())
    try:
        graph = explore_product(data, automaton)
        generate_uppaal_model(automaton, data=data)
    except (UppaalError, Unrepresentable, EvaluationError, ModelRangeError):
        assume(False)
        return
    exact = not truncates(automaton, data.scale)
    episodes = EpisodeBatch(CheckedProgram(automaton, data), goal=None)
    rng = np.random.default_rng(seed)
    for _ in range(5):
        actions = walk(graph, graph.initial, rng)
        nodes = engine_path(graph, data.decide_every, actions)
        episodes.reset(1)
        for step, action in enumerate(actions):
            result = episodes.step(np.array([action]))
            k = int(episodes.k[0])
            node = nodes.get((k, ENDED), nodes[(k, SAMPLED)])
            where = f"actions {actions[:step + 1]}, sample {k}"
            assert automaton.location_names[int(episodes.location[0])] == \
                automaton.location_names[int(graph.location[node])], where
            if exact:
                for reward in automaton.rewards:
                    assert float(episodes.rewards[reward][0]) * data.scale == pytest.approx(
                        int(graph.mirrors[reward][node]), rel=1e-9, abs=1e-6), (where, reward)
            assert bool(result.ended[0] or result.truncated[0]) == bool(graph.terminal()[node]), where
        assert episodes.done[0]
        assert episodes.clipped == 0


# ---------------------------------------------------------------- generated programs in a scenario
#: C's keywords, which UPPAAL allows as names (the fuzzer's Python names include `float`, `long`...):
#: a model that uses one is valid UPPAAL, but this test cannot compile it as C.
C_KEYWORDS = frozenset((
    "auto break case char const continue default do double else enum extern float for goto if inline int long "
    "register restrict return short signed sizeof static struct switch typedef union unsigned void volatile while "
    "_Bool _Complex _Imaginary").split())


def c_compatible(automaton: ir.Automaton) -> bool:
    """Whether no name of ``automaton`` that the emitted model declares is a C keyword."""
    names = [automaton.name, *automaton.location_names, *automaton.rewards, *(i.name for i in automaton.inputs),
             *(name for name, _ in automaton.constants), *(p.name for p in automaton.parameters)]
    return not C_KEYWORDS.intersection(names)


#: The names the whole model's harness reads as they are (its channels, the ground truth's template, the
#: constants it reads from the library): where a .ra name takes one, the target renames its own (`STEPS_`:
#: valid UPPAAL, and what UPPAAL's parser checks), which the harness does not follow.
HARNESS_NAMES = frozenset(("accrue", "read", "sense", "decide", "finish", GROUND_TRUTH, "STEPS", "DECIDE_EVERY",
                           "JERK_VALUES", "TURN_VALUES"))


def in_tiny_scene(text: str, folder: Path) -> Path | None:
    """A generated program with a ``model`` block (fuzzgen: it names the left turn) moved into the tiny
    scenario avoidable_obstacle over 2 s, with 3 x 3 actions where it keeps the defaults (the product stays
    small); None without a model block."""
    if f'scenario "{fuzzgen.SCENARIO}"' not in text:
        return None
    tiny = TINY_SCENARIOS["avoidable_obstacle"]()
    tiny.write(folder)
    scene = f'scenario "{tiny.name}.xml"'
    text = re.sub(r"\bhorizon [0-9.]+", "horizon 2", text.replace(f'scenario "{fuzzgen.SCENARIO}"', scene), count=1)
    for action, line in (("jerk", "action jerk in [-2, 2] step 2"), ("turn", "action turn in [-0.2, 0.2] step 0.2")):
        if f"action {action}" not in text:
            text = text.replace(scene, f"{scene}\n    {line}")
    path = folder / "generated.ra"
    path.write_text(text, encoding="utf-8")
    return path


@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large])
@given(program=fuzzgen.programs(), seed=st.integers(0, 2**16))
def test_generated_programs_run_alike_in_the_emitted_network_and_the_product(
        program: Any, seed: int, tmp_path_factory: pytest.TempPathFactory) -> None:
    """The fuzzer's programs (tests/support/fuzzgen.py) ran alone only: their `model` blocks (exponents,
    decide periods, granularity, `dynamics increments`, `collision sticky`, `offroad_from`, `allow when`,
    bindings of every kind), `*` edges and constants never met the product. Each valid one with a model
    block, in a tiny scenario, along random action sequences, as above."""
    assume(program.kind == "valid")
    folder = Path(tempfile.mkdtemp(dir=tmp_path_factory.getbasetemp()))
    path = in_tiny_scene(program.text, folder)
    assume(path is not None)
    assert path is not None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = compile_file(path)
    assume(result.ok)
    automaton, data = result.raise_for_errors(), result.model_data
    try:
        model = generate_uppaal_model(automaton, data=data)
    except (UppaalError, Unrepresentable):
        assume(False)  # E0801
        return
    xml = validated(model, folder, "generated")  # UPPAAL's parser reads it, whatever its names
    assume(c_compatible(automaton) and not HARNESS_NAMES.intersection(
        [*automaton.location_names, *automaton.rewards, *(i.name for i in automaton.inputs),
         *(name for name, _ in automaton.constants), *(p.name for p in automaton.parameters)]))
    try:
        graph = explore_product(data, automaton, max_states=300_000)
    except (EvaluationError, ModelRangeError, BudgetExceeded):
        assume(False)  # two edges enabled where the bindings break `assume`, beyond int32 or the budget
        return
    assert Comparison(Scenario(automaton, data, xml, graph), folder).run_many(seed, runs=3) >= 3
    event(f"compared ({graph.n_states // 1000 * 1000:,}+ product states)")
