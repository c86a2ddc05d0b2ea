"""Random `.ra` programs for the fuzzer (tests/support/fuzz.py): a generator that knows the shape of a file.

:func:`generate` writes one automaton, declaration by declaration (inputs, ``assume``, constants,
rewards, priority, objective, timing, locations, edges, ``at end``, ``episode ends when``, ``goal
when`` and ``collision when``, queries, a ``model`` block), and
randomises inside that shape. Most programs are built to pass ``rac check``, so that ``rac fmt``
and both compile targets see them too:

- edge guards are the leaves of a random decision tree over the inputs (a boolean, or a numeric
  input below and above a threshold), so two edges leaving one location are never both enabled;
- with a ``priority``, each location gets a *profile*: the first reward whose rate is negative
  there (every reward above it has a rate >= 0, every reward below it <= 0: P1), and every edge
  into a location that penalises a reward P2 watches lowers it by a penalty sized from the most
  everything below it can gain over the horizon (P2);
- horizons stay within a few dozen samples and numbers small, so the int32 range check passes.

Each program has a *kind*: ``valid`` (built to check), ``extreme`` (valid, with extreme values in
places that still check: constants such as 1e308, 0, -0.0 or a 40-digit integer, thresholds far
outside an input's range, names that UPPAAL reserves or the emitted model also uses), or ``near
miss`` (one or two defects: a required declaration dropped, a keyword as a name, overlapping
guards, a penalty too small, an unknown name, an out-of-range number, a huge action grid in the
``model`` block (E0901)...). Any kind sometimes names its automaton, locations, rewards, inputs or
constants after Python builtins and keywords (``float``, ``len``, ``ValueError``, ``math``,
``class``, ``None``: :data:`PYTHON_NAMES`), which the Python target must rename.

The choices come from a :class:`Choices`, of which there are two:

- :class:`RandomChoices` (a seeded ``random.Random``) drives the long runs of ``python
  tests/support/fuzz.py --source generate``: fast, reproducible from its seed, and it goes on after a
  failure so that the run can count every outcome;
- :func:`programs` is a hypothesis strategy (``st.composite``) that draws the same choices from
  hypothesis, so the suite runs a bounded number of examples with ``@given`` and a failure shrinks
  towards a small program (every choice shrinks to its first, simplest option, and a chance to
  False). A ``@given`` run stops at the first failure to shrink it, and ``.example()`` is for
  interactive use only, which is why the long run does not use hypothesis.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Protocol, TypeVar

from hypothesis import strategies as st

T = TypeVar("T")

#: The scenario every generated ``model`` block names (tests/support/fuzz.py copies it next to the input).
SCENARIO = "left_turn.xml"
KINDS = ("valid", "extreme", "near miss")

# Name pools, the plainest first (hypothesis shrinks towards it). Besides ordinary names they hold
# words UPPAAL reserves (`clock`, `init`, `sum`, `A`), names the emitted model uses itself (`Timer`,
# `count`, `iSa`, `PERIOD`, `x`) and words that are keywords of rac only in some places (`step`).
AUTOMATA = ("Driving", "Car", "A1", "Lanes", "Timer", "clock", "system", "Pr", "E")
INPUTS = ("isClose", "prog", "comf", "collide", "near", "slow", "b", "step", "bind", "scenario", "action",
          "chan", "sum", "sense", "read", "count", "clock_", "forall", "head", "Start", "x", "time", "crashed",
          "in_road", "saturated", "OBS_N", "goal", "collision", "episode", "require", "ends")
REWARDS = ("sa", "pr", "co", "safety", "speed", "r", "iSa", "SCALE", "double", "cost", "hybrid")
LOCATIONS = ("Normal", "Unsafe", "Stalled", "Uncomfortable", "Go", "Near", "Idle", "init", "Running",
             "Timer", "Dynamics", "urgent", "commit", "PERIOD", "L0", "Sensing", "A", "Init", "Moving", "TD")
CONSTANTS = ("PENALTY", "K", "W", "BONUS", "LIMIT", "MAXD", "N", "const_", "INT32_MAX", "STEPS", "THD", "SCALE_D",
             "P1", "WIDTH", "M_PI", "DBL_MAX")
QUERIES = ("Qe", "Qh", "Q1", "Q2", "Q3", "Q4", "Q5", "Q6", "Q7", "Q8")
STRATEGIES = ("safe", "reach", "S0", "S1", "fast")
#: Words a near miss uses as a name: rac's keywords (most are a syntax error there, some not).
KEYWORDS = ("location", "edge", "when", "do", "input", "at", "end", "in", "every", "automaton", "const",
            "reward", "query", "initial", "strict", "true", "not", "and", "imply", "model", "priority",
            "objective", "horizon", "sample", "under", "strategy", "bool", "real", "int")
#: Extreme values that still check as an unused constant or a threshold far outside a range.
EXTREME = ("1e308", "0", "-0.0", "123456789012345678901234567890123456789", "1e-300", "0.0000001",
           "2147483648", "2147483647", "-2147483648", "4294967296", "1e15", "0.1e1", "1e-7", "99999.99999")
#: Numbers that break a declaration when a near miss puts them in a number's place.
BREAKING = ("1e5000", "1e-5000", "0", "-0.0", "1e308", "9" * 60, "0.0000001", "-1", "1e400")
DEFECTS = ("drop", "keyword", "overlap", "cheap", "unknown", "reward guard", "nonlinear", "number",
           "duplicate", "bounds", "two inputs", "model", "query", "huge grid", "requirement")
#: Names the Python target must not shadow: builtins, modules and names of the generated module,
#: and Python keywords (all of them names in `.ra`); the generated module renames what would clash.
PYTHON_NAMES = ("float", "bool", "len", "type", "ValueError", "math", "list", "print", "self", "None", "True",
                "False", "def", "class", "lambda", "pass", "return", "yield", "import", "from", "global", "with",
                "as", "is", "if", "else", "for", "while", "try", "except", "raise", "del", "assert", "async",
                "await", "nonlocal", "str", "object", "super", "id", "max", "min", "abs", "Mapping", "inputs",
                "reset", "step")
#: Action grids past the limit of issue 22 (E0901 at once, never a hang): a near miss's "huge grid".
HUGE_GRIDS = ("action jerk in [-20000000, 20000000] step 0.01", "action turn in [0, 1] step 1e-9",
              "action jerk in [-1e300, 1e300] step 1e-300")


class Choices(Protocol):
    """Where a generator's decisions come from."""

    def integer(self, low: int, high: int) -> int:
        """A whole number in [low, high] (``low`` is the simplest)."""

    def chance(self, percent: int) -> bool:
        """True in about ``percent`` % of the draws (False is the simpler answer)."""


class RandomChoices:
    """Choices from a seeded ``random.Random``: the long runs."""

    def __init__(self, rng: random.Random):
        self.rng = rng

    def integer(self, low: int, high: int) -> int:
        return self.rng.randint(low, high)

    def chance(self, percent: int) -> bool:
        return self.rng.randrange(100) < percent


class HypothesisChoices:
    """Choices drawn from hypothesis (inside ``st.composite``): the suite, with shrinking."""

    def __init__(self, draw: Callable[[st.SearchStrategy[int]], int]):
        self.draw = draw

    def integer(self, low: int, high: int) -> int:
        return self.draw(st.integers(low, high))

    def chance(self, percent: int) -> bool:
        return self.draw(st.integers(0, 99)) >= 100 - percent  # shrinks to 0: False


def pick(c: Choices, options: Sequence[T]) -> T:
    """One of ``options`` (the first is the simplest)."""
    return options[c.integer(0, len(options) - 1)]


@dataclass(frozen=True)
class Generated:
    """A generated program: its text, its kind (:data:`KINDS`) and the defects of a near miss."""

    text: str
    kind: str
    defects: tuple[str, ...] = ()


@dataclass
class _Input:
    name: str
    kind: str  # "bool", "real" or "int"
    low: Fraction = Fraction(0)
    high: Fraction = Fraction(0)


@dataclass
class _Location:
    name: str
    profile: int | None = None  # the first reward (in priority order) with a negative rate here
    rates: dict[str, tuple[str, Fraction]] = field(default_factory=dict)  # reward -> (text, largest value)


def _number(value: Fraction) -> str:
    """``value`` as a `.ra` literal (a fraction that no decimal holds is written ``n / d``)."""
    if value.denominator == 1:
        return str(value.numerator) if value >= 0 else f"-{-value.numerator}"
    text = f"{float(abs(value)):.10g}"
    if Fraction(text) != abs(value):
        text = f"({abs(value.numerator)} / {value.denominator})"
    return text if value >= 0 else f"-{text}"


class _Builder:
    """One program under construction (the module docstring says how it stays valid)."""

    def __init__(self, c: Choices):
        self.c = c
        roll = c.integer(0, 9)
        self.kind = "valid" if roll < 5 else "extreme" if roll < 7 else "near miss"
        self.defects: set[str] = set()
        if self.kind == "near miss":
            self.defects = {pick(c, DEFECTS) for _ in range(c.integer(1, 2))}
        self.used: set[str] = set()
        self.automaton = ""
        self.namesake = False  # a declaration is named like the automaton
        self.inputs: list[_Input] = []
        self.consts: dict[str, Fraction] = {}
        self.lines: dict[str, list[str]] = {}  # group -> declarations
        self.rewards: list[str] = []  # in priority order
        self.weights: list[Fraction] = []  # their weights in the objective (> 0)
        self.prioritised = self.strict = False
        self.period = self.horizon = Fraction(1)
        self.samples = 1
        self.numeric: list[_Input] = []  # numeric inputs >= 0
        self.locations: list[_Location] = []

    # ------------------------------------------------------------ names and values
    def name(self, pool: Sequence[str], plain: int = 4) -> str:
        """A fresh name: mostly from the first ``plain`` of ``pool``; an extreme program also takes
        the troublemakers further down the pool, a near miss with "keyword" sometimes a keyword."""
        if "keyword" in self.defects and self.c.chance(10):
            return pick(self.c, KEYWORDS)
        if "duplicate" in self.defects and self.used and self.c.chance(5):
            return sorted(self.used)[0]
        if self.kind == "extreme" and self.automaton and not self.namesake and self.c.chance(5):
            self.namesake = True  # named like the automaton: its own namespace in .ra, not in UPPAAL
            return self.automaton
        top = len(pool) if self.kind == "extreme" or self.c.chance(15) else min(plain, len(pool))
        if self.c.chance(12 if self.kind == "extreme" else 3):
            pool, top = PYTHON_NAMES, len(PYTHON_NAMES)  # a Python builtin or keyword
        for _ in range(4):
            candidate = pool[self.c.integer(0, top - 1)]
            if candidate not in self.used:
                break
        else:
            candidate = f"{pool[0]}{len(self.used)}"
        if self.kind == "extreme" and self.c.chance(3):
            candidate = candidate + "_" * 200 + "z"  # long, within the name limit
        while candidate in self.used:
            candidate += "_"
        self.used.add(candidate)
        return candidate

    def literal(self, value: Fraction) -> str:
        """``value`` as a literal; a near miss with "number" sometimes breaks it."""
        if "number" in self.defects and self.c.chance(12):
            return pick(self.c, BREAKING)
        return _number(value)

    def value_or_const(self, value: Fraction) -> str:
        """``value``, or a constant that holds it when one does."""
        same = [n for n, v in self.consts.items() if v == value]
        if same and self.c.chance(40):
            return pick(self.c, same)
        return self.literal(value)

    def add(self, group: str, line: str) -> None:
        self.lines.setdefault(group, []).append(line)

    # ------------------------------------------------------------ declarations
    def declare_inputs(self) -> None:
        for _ in range(self.c.integer(1, 4)):
            self.inputs.append(_Input(self.name(INPUTS), "bool"))
        for _ in range(self.c.integer(0, 2) if self.c.chance(60) else 0):
            kind = pick(self.c, ("real", "int"))
            low = pick(self.c, (Fraction(0), Fraction(-10), Fraction(1)))
            high = low + pick(self.c, (Fraction(50), Fraction(10), Fraction(3), Fraction(500)))
            self.inputs.append(_Input(self.name(("d", "dgoal", "gap", "lane", "v", "mindist", "u")), kind, low, high))
        groups: list[list[_Input]] = []
        for item in self.inputs:  # neighbours of one type may share a declaration
            if groups and groups[-1][0].kind == item.kind == "bool" and self.c.chance(30):
                groups[-1].append(item)
            else:
                groups.append([item])
        for group in groups:
            names = ", ".join(i.name for i in group)
            first = group[0]
            if first.kind == "bool":
                self.add("input", f"input {names} : bool")
            elif "bounds" in self.defects and self.c.chance(50):
                self.add("input", f"input {names} : {first.kind}" + pick(self.c, (
                    "", f" in [{first.high}, {first.low}]", " in [0.5, 2.5]" if first.kind == "int" else " in [1, 0]")))
            else:
                self.add("input", f"input {names} : {first.kind} in [{self.value_or_const(first.low)}, "
                                  f"{self.value_or_const(first.high)}]")

    def declare_consts(self) -> None:
        for _ in range(self.c.integer(0, 3)):
            name = self.name(CONSTANTS)
            if self.consts and self.c.chance(30):  # from an earlier constant
                other = pick(self.c, sorted(self.consts))
                self.consts[name] = self.consts[other] / 4 + 1
                self.add("const", f"const {name} = {other} / 4 + 1")
            else:
                value = pick(self.c, (Fraction(100), Fraction(2), Fraction(1, 2), Fraction(10), Fraction(1, 3)))
                self.consts[name] = value
                self.add("const", f"const {name} = {self.literal(value)}")
        if self.kind == "extreme":
            for _ in range(self.c.integer(1, 3)):
                self.add("const", f"const {self.name(CONSTANTS, len(CONSTANTS))} = {pick(self.c, EXTREME)}")
        if self.c.chance(10):
            self.add("const", f"const {self.name(('ON', 'OFF', 'FLAG'))} = {pick(self.c, ('true', 'false'))}")

    # ------------------------------------------------------------ guards
    def literals(self, item: _Input, outside: bool = False) -> tuple[str, str]:
        """A condition on one input and its negation."""
        c = self.c
        if item.kind == "bool":
            return pick(c, ((item.name, f"!{item.name}"), (item.name, f"not {item.name}"),
                            (f"{item.name} == true", f"{item.name} == false"), (f"!!{item.name}", f"!{item.name}")))
        if outside:  # far beyond the range: one side is never true (a warning, not an error)
            limit = pick(c, EXTREME)
            return f"{item.name} < {limit}", f"{item.name} >= {limit}"
        span = item.high - item.low
        threshold = item.low + span * Fraction(c.integer(1, 3), 4)
        if item.kind == "int":
            threshold = Fraction(int(threshold))
        t = self.value_or_const(threshold)
        return pick(c, ((f"{item.name} < {t}", f"{item.name} >= {t}"),
                        (f"{t} > {item.name}", f"!({item.name} < {t})"),
                        (f"2*{item.name} + 1 < 2*{t} + 1", f"{item.name} >= {t}"),
                        (f"{item.name} <= {t}", f"{item.name} > {t}")))

    def tree(self, depth: int, tested: frozenset[str] = frozenset()) -> list[list[str]]:
        """Disjoint conditions (each a list of conjuncts) that together cover every input valuation
        (a boolean input is tested once on a path: a second test would only make dead edges)."""
        candidates = [i for i in self.inputs if i.kind != "bool" or i.name not in tested]
        if depth == 0 or not candidates or self.c.chance(15):
            return [[]]
        item = pick(self.c, candidates)
        yes, no = self.literals(item, outside=self.kind == "extreme" and self.c.chance(10))
        below = tested | {item.name}
        return ([[yes, *leaf] for leaf in self.tree(depth - 1, below)]
                + [[no, *leaf] for leaf in self.tree(depth - 1, below)])

    def guard(self, conjuncts: list[str]) -> str:
        if not conjuncts:
            return ""
        joined = pick(self.c, (" && ", " and ")).join(
            f"({part})" if (" " in part and self.c.chance(20)) or "not " in part else part for part in conjuncts)
        return f" when {joined}"

    # ------------------------------------------------------------ the automaton
    def build(self) -> str:
        c = self.c
        automaton = self.automaton = self.name(AUTOMATA, 3)
        self.declare_consts()
        self.declare_inputs()
        if len([i for i in self.inputs if i.kind == "bool"]) >= 2 and c.chance(30):
            first, second = [i.name for i in self.inputs if i.kind == "bool"][:2]
            self.add("assume", f"assume {first} imply {second}" if c.chance(70) else f"assume {first} || {second}")
        self.declare_rewards()
        self.period = pick(c, (Fraction(1), Fraction(1, 2), Fraction(1, 10), Fraction(1, 4), Fraction(2)))
        self.samples = pick(c, (10, 5, 20, 30, 3, 1))
        self.horizon = self.period * self.samples
        self.add("sample", f"sample every {self.literal(self.period)}")
        off = Fraction(1, 3) if "number" in self.defects else Fraction(0)  # not a whole number of periods
        self.add("horizon", f"horizon {self.literal(self.horizon + off)}")
        self.numeric = [i for i in self.inputs if i.kind != "bool" and i.low >= 0]  # rates from these stay >= 0
        self.declare_locations()
        if "reward guard" in self.defects:
            self.inputs.append(_Input(self.rewards[0], "bool"))  # a reward read as a condition: E0202
        self.declare_edges()
        model = c.chance(30) or "model" in self.defects or "huge grid" in self.defects
        self.queries(automaton, [loc.name for loc in self.locations], model)
        if model:
            self.model_block()
        self.outcomes()
        if "drop" in self.defects:
            victim = pick(c, ("objective", "horizon", "sample", "location", "reward", "input"))
            self.lines.pop(victim, None)
        return self.render(automaton)

    def declare_rewards(self) -> None:
        """Rewards (in priority order), the priority and the objective (positive weights)."""
        c = self.c
        self.rewards = rewards = [self.name(REWARDS, 3) for _ in range(c.integer(1, 3))]
        self.weights = [pick(c, (Fraction(1), Fraction(10), Fraction(5), Fraction(2), Fraction(3))) for _ in rewards]
        self.prioritised = c.chance(60)
        self.strict = self.prioritised and c.chance(25)
        declared = list(rewards)
        if c.chance(30):
            declared.reverse()
        self.add("reward", "reward " + ", ".join(declared))
        if self.prioritised:
            order = list(rewards)
            if "cheap" in self.defects and len(order) > 1 and c.chance(30):
                order = order[:-1]  # E0404
            self.add("priority", "priority " + ("strict " if self.strict else "") + " > ".join(order))
        terms = []
        # Weights to synthesise, from the weight upwards: the least point of the set is the weight itself
        # (it passes), so a valid program stays valid and the synthesis runs on every kind of program.
        parametrised = c.chance(12)
        for reward, weight in zip(rewards, self.weights, strict=True):
            if parametrised and c.chance(70):
                w = f"w_{reward}"
                high = weight + pick(c, (Fraction(0), Fraction(1), Fraction(5)))
                self.add("const", f"param {w} in [{self.literal(weight)}, {self.literal(high)}]")
                terms.append(pick(c, (f"{w}*{reward}", f"{reward} * {w}")))
                continue
            w = self.value_or_const(weight)
            terms.append(reward if weight == 1 and c.chance(70) else pick(c, (f"{w}*{reward}", f"{reward} * {w}")))
        if not self.prioritised and c.chance(20):
            terms[0] = f"-{terms[0]}"  # a negative weight: fine without a priority
        if "nonlinear" in self.defects and c.chance(50):
            terms.append(pick(c, (f"{rewards[0]} * {rewards[-1]}", self.inputs[0].name)))
        self.add("objective", "objective " + " + ".join(terms))

    def declare_locations(self) -> None:
        """Locations with their profiles and rates (the first is initial and penalises no reward
        P2 watches)."""
        c, rewards = self.c, self.rewards
        self.locations = [_Location(self.name(LOCATIONS, 4)) for _ in range(c.integer(1, 5))]
        for index, location in enumerate(self.locations):
            lowest = 1 if index == 0 else 0
            if self.prioritised and (index > 0 or not self.strict) and lowest < len(rewards) and c.chance(45):
                location.profile = c.integer(lowest, len(rewards) - 1)
            profile = location.profile
            for position, reward in enumerate(rewards):
                if not c.chance(75):
                    continue
                if self.prioritised and profile is not None and position == profile:
                    location.rates[reward] = (pick(c, ("-1", "-2", "-0.5")), Fraction(0))
                elif self.prioritised and profile is not None and position > profile:
                    if not self.strict:  # strict: 0, else the level below would be penalised here too
                        location.rates[reward] = pick(c, (("0", Fraction(0)), ("-1", Fraction(0))))
                elif self.numeric and c.chance(25):
                    item = pick(c, self.numeric)
                    location.rates[reward] = (f"{item.name} / 50", item.high / 50)
                elif self.prioritised:
                    rate = pick(c, (Fraction(1), Fraction(0), Fraction(2), Fraction(1, 2)))
                    location.rates[reward] = (self.value_or_const(rate), rate)
                else:
                    rate = pick(c, (Fraction(1), Fraction(-1), Fraction(0), Fraction(2), Fraction(1, 2)))
                    location.rates[reward] = (self.literal(rate), max(rate, Fraction(0)))
            if "nonlinear" in self.defects and c.chance(30):
                location.rates[rewards[0]] = (f"{rewards[-1]} + 1", Fraction(1))
        for location in self.locations:
            flows = "; ".join(f"{r}' == {text}" for r, (text, _) in location.rates.items())
            if flows and c.chance(20):
                flows += ";"
            prefix = "initial " if location is self.locations[0] else ""
            self.add("location", f"{prefix}location {location.name} {{ {flows} }}" if flows
                     else f"{prefix}location {location.name} {{ }}")

    def declare_edges(self) -> None:
        """Edges and ``at end`` clauses. The leaves of a decision tree go to `*` edges; the leaves
        left free, and the one of the `*` edge into a location, to edges out of each location."""
        c, rewards, locations = self.c, self.rewards, self.locations
        edges: list[tuple[str, _Location, list[str]]] = []  # source, target, guard conjuncts
        free: list[tuple[list[str], _Location | None]] = []
        for leaf in self.tree(pick(c, (2, 1, 3, 0))):
            if c.chance(60):
                target = pick(c, locations)
                edges.append(("*", target, leaf))
                free.append((leaf, target))
            else:
                free.append((leaf, None))
        for source in locations:
            for leaf, star_target in free:
                if (star_target is None or star_target is source) and c.chance(50):
                    edges.append((source.name, pick(c, locations), leaf))
        if "overlap" in self.defects and edges:
            edges.append(edges[0])

        bonus = {r: Fraction(0) for r in rewards}  # the most one edge adds
        end_bonus = {r: Fraction(0) for r in rewards}  # what every `at end` together adds
        for _ in range(c.integer(0, 2)):
            reward = pick(c, rewards)
            amount = pick(c, (Fraction(100), Fraction(1), Fraction(5)))
            end_bonus[reward] += amount
            leaf = pick(c, self.tree(1))
            self.add("end", f"at end{self.guard(leaf)} do {reward} += {self.value_or_const(amount)}")
        updates: list[list[tuple[str, str, Fraction]]] = []
        for _, target, _ in edges:
            changes = []
            for position, reward in enumerate(rewards):
                if target.profile == position or not c.chance(30):
                    continue
                # lowering a reward P2 watches would make the target penalise it
                lowers = not self.prioritised or (position > 0 and not self.strict)
                amount = pick(c, (Fraction(1), Fraction(5), Fraction(10), Fraction(1, 2)))
                sign = "-" if lowers and c.chance(40) else "+"
                changes.append((reward, sign, amount))
                if sign == "+":
                    bonus[reward] = max(bonus[reward], amount)
            updates.append(changes)

        penalty = self.penalties(bonus, end_bonus)
        for (source_name, target, leaf), changes in zip(edges, updates, strict=True):
            parts = []
            if target.profile is not None:
                reward = rewards[target.profile]
                amount = self.value_or_const(penalty[target.profile])
                parts.append(pick(c, (f"{reward} -= {amount}", f"{reward} = {reward} - {amount}")))
            for reward, sign, value in changes:
                text = self.value_or_const(value)
                parts.append(pick(c, (f"{reward} {sign}= {text}", f"{reward} = {reward} {sign} {text}")))
            if self.numeric and not self.prioritised and c.chance(15):
                parts.append(f"{rewards[-1]} += {pick(c, self.numeric).name} / 10")
            do = (" do " + ", ".join(parts)) if parts else ""
            self.add("edge", f"edge {source_name} -> {target.name}{self.guard(leaf)}{do}")
        if "unknown" in self.defects:
            self.add("edge", f"edge {locations[0].name} -> {locations[-1].name} when {self.inputs[0].name}x")
        if "two inputs" in self.defects and len(self.numeric) >= 2:
            self.add("edge", f"edge * -> {locations[0].name} when {self.numeric[0].name} < {self.numeric[1].name}")

    def penalties(self, bonus: dict[str, Fraction], end_bonus: dict[str, Fraction]) -> dict[int, Fraction]:
        """The penalty of each reward (by position): more than what it and the rewards below it
        (all rewards, without `strict`) can gain, weighted, over the whole run, divided by its weight."""
        gain = {}
        for reward in self.rewards:
            rate = max((loc.rates.get(reward, ("", Fraction(0)))[1] for loc in self.locations), default=Fraction(0))
            gain[reward] = rate * self.horizon + bonus[reward] * self.samples + end_bonus[reward]
        penalty: dict[int, Fraction] = {}
        for position, weight in enumerate(self.weights):
            watched = self.rewards[position:] if self.strict else self.rewards
            total = sum((gain[r] * w for r, w in zip(self.rewards, self.weights, strict=True) if r in watched),
                        Fraction(0))
            penalty[position] = Fraction(1) if "cheap" in self.defects else Fraction(int(total / weight) + 1)
        if self.prioritised and self.c.chance(50):
            big = max(penalty.values())
            name = self.name(("PENALTY", "P", "COST"))
            self.add("const", f"const {name} = {self.literal(big)}")
            self.consts[name] = big
        return penalty

    # ------------------------------------------------------------ queries and the model
    def queries(self, automaton: str, locations: list[str], model: bool) -> None:
        c, rewards = self.c, self.rewards
        here = pick(c, locations)
        place = pick(c, (here, f"{automaton}.{here}"))
        bound = self.value_or_const(self.horizon)
        reward = pick(c, rewards)
        condition = pick(c, [i.name for i in self.inputs if i.kind == "bool"] or ["true"])
        # (an input named `time` hides UPPAAL's clock)
        eventually = f"A<> time >= {bound}" if "time" not in self.used else f"A<> {place}"
        forms = [f"A[] {condition} imply {place}", f"E<> {place}", f"E[] !{place}", eventually,
                 f"{condition} --> {place}", f"Pr[<={bound}](<> {place})", f"Pr[<={bound}; 100](<> {place})",
                 f"Pr[<={bound}](<> {place}) >= {pick(c, ('0.9', '0', '1', '1e-9'))}",
                 f"E[<={bound}; 10](max: {reward})", f"simulate[<={bound}; 5]{{{', '.join(rewards)}}}",
                 f"A[] {reward} <= {pick(c, ('1e6', '1e308', '0', '2147483647', '-0.0'))}",
                 f"Pr[#<={pick(c, ('10', '1'))}](<> {place})", f"A[] not deadlock or {place}"]
        if model:
            forms += ["A[] !collide() && !offroad()", "E<> goal()", f"Pr[<={bound}](<> fabs(true_x - x) >= 0.5)",
                      "A[] mindist() >= 0", f"E<> v > 3 && {place}"]
        strategies: list[str] = []
        for _ in range(c.integer(0, 4)):
            name = self.name(QUERIES)
            if c.chance(15):
                strategy = self.name(STRATEGIES)
                goal = pick(c, (f"A[] !{place}", f"E<> {place}"))
                if model and c.chance(50):
                    self.add("query", f"query {name}: strategy {strategy} = maxE({reward})[<={bound}]"
                                      f"{{{automaton}.location}}->{{x, v}}: <> goal()")
                else:
                    self.add("query", f"query {name}: strategy {strategy} = control: {goal}")
                strategies.append(strategy)
                continue
            form = pick(c, forms)
            if strategies and c.chance(40) and not form.startswith("simulate"):
                form += f" under {pick(c, strategies)}"
            elif "query" in self.defects and c.chance(40):
                form = pick(c, (f"A[] {place} under nothing", f"Pr[<={self.inputs[-1].name}](<> {place})",
                                f"E<> {place} imply", "A[] collide()"))
            self.add("query", f"query {name}: {form}")

    def outcomes(self) -> None:
        """Issue 25's declarations now and then: ``episode ends when``, ``goal when`` and ``collision
        when`` over the inputs; a near miss with "requirement" gets a ``require`` the checker refuses
        (E1009, E1010). Valid programs get no ``require``: whether one holds is the analyses' to say."""
        c = self.c
        declared = set()
        for word in ("episode ends", "goal", "collision"):
            if c.chance(12):
                condition = self.guard(pick(c, self.tree(1))).removeprefix(" when ") or "true"
                self.add("outcome", f"{word} when {condition}")
                declared.add(word)
        if "requirement" in self.defects:
            wrong = ["require riks", "require stalling_never_pays <= 1", "require risk", "require risk <= 2"]
            if "goal" not in declared:
                wrong.append("require goal_earlier_never_pays_less")
            self.add("require", pick(c, wrong))

    def model_block(self) -> None:
        c = self.c
        items = [f'scenario "{SCENARIO}"']
        if "model" in self.defects and c.chance(30):
            items = []  # E0105
        if c.chance(40):
            # outside a near miss, an exponent that holds each rate's growth per sample (E0801): the
            # rates are halves, whole numbers and `input / 50`
            held = min(e for e in range(6) if all((step * self.period * 10**e).denominator == 1
                                                  for step in (Fraction(1, 2), Fraction(1, 50))))
            exponents = [e for e in (2, 3, 4, 1, 5) if self.kind == "near miss" or e >= held]
            items.append(f"exponent {pick(c, exponents)}")
        if c.chance(30):
            items.append(f"decide_period {self.literal(self.period * pick(c, (2, 1, 5)))}")
        if c.chance(20):
            items.append(f"granularity {pick(c, ('0.5', '1', '0.25'))}")
        if c.chance(20):
            items.append(pick(c, ("action jerk in [-2, 2] step 2", "action turn in [0, 0.4] step 0.2",
                                  "action jerk in [0, 0] step 1")))
        for setting in ("dynamics increments", "collision sticky", "offroad_from 1", "collision_distance 1",
                        "max_speed 30", "sensor_error 0.25"):
            if c.chance(8):
                items.append(setting)
        if "model" in self.defects:
            items.append(pick(c, ("exponent 9", "colour 3", "decide_period 0.33", "action brake in [0, 1] step 1",
                                  "granularity 0.3")))
        if "huge grid" in self.defects:
            items.append(pick(c, HUGE_GRIDS))
        for item in self.inputs:
            if "model" in self.defects and c.chance(20):
                continue  # E0709
            if item.kind == "bool":
                value = pick(c, ("collide()", "mindist() < 3 * collision_distance", "dist_goal() < prev(dist_goal())",
                                 "offroad()", "goal()", "fabs(acc) < comfort_acceleration * max_acceleration",
                                 "v > 5", "time >= 2"))
            else:
                value = pick(c, ("dist_goal()", "mindist()", "v", "fmin(mindist(), 50)"))
            items.append(f"bind {item.name} = {value}")
        if c.chance(10):
            items.append("allow when turn == 0 || (fabs(head) <= 0.2 && !offroad())")
        if c.chance(30):
            items.reverse()
        self.add("model", "model {\n" + "\n".join(f"    {item}" for item in items) + "\n}")

    # ------------------------------------------------------------ text
    def render(self, automaton: str) -> str:
        c = self.c
        order = ["input", "assume", "const", "reward", "priority", "objective", "sample", "horizon", "location",
                 "edge", "end", "outcome", "require", "query", "model"]
        if c.chance(15):  # any order works (only constants must come after those they use)
            rest = order[:2] + order[3:]
            random.Random(c.integer(0, 1000)).shuffle(rest)
            order = ["const", *rest]
        indent = pick(c, ("    ", "\t", "  ", ""))
        comments = c.chance(30)
        out = [f"// generated ({self.kind})"] if comments else []
        out.append(f"automaton {automaton} {{")
        for group in order:
            for line in self.lines.get(group, []):
                if comments and c.chance(10):
                    out.append(f"{indent}// before {group}")
                text = line.replace("\n", "\n" + indent)
                if comments and c.chance(10):
                    text += pick(c, ("  // trailing", "  /* block */", "  /* two\n   lines */"))
                out.append(indent + text)
            if c.chance(30):
                out.append("")
        out.append("}")
        separator = "\r\n" if c.chance(5) else "\n"
        return separator.join(out) + separator


def generate(c: Choices) -> Generated:
    """One random program, with the choices of ``c``."""
    builder = _Builder(c)
    text = builder.build()
    return Generated(text, builder.kind, tuple(sorted(builder.defects)))


@st.composite
def programs(draw: Callable[[st.SearchStrategy[int]], int]) -> Generated:
    """The hypothesis strategy of :func:`generate`."""
    return generate(HypothesisChoices(draw))
