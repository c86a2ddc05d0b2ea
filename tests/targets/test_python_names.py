"""The Python target under every name a `.ra` file may give: builtins, keywords, the module's own names.

The generated module's helpers read module-level names (``float``, ``isinstance``, ``math``,
``_key_error`` ...); the automaton's class is the one module-level name a `.ra` file chooses, so
it must never shadow them. Inputs, rewards and locations become prefixed locals, slots and
strings; they are checked the same way. Each case compiles, imports the module, steps it and
compares every step bit for bit with the interpreter behind ``rac.load``.
"""

from __future__ import annotations

import builtins
import keyword
import struct
import symtable
import types
from pathlib import Path

import pytest

from rac.cli.main import main
from rac.compiler import compile_text
from rac.runtime.interpreter import RewardAutomaton
from rac.targets.python import MODULE_IMPORTS, RESERVED_NAMES, generate_python, python_class_name

#: The module's own top-level names (imports, helpers) and the names Python gives every module.
MODULE_NAMES = ("annotations", "math", "numbers", "Mapping", "_key_error", "_mapping", "_boolean", "_number",
                "_range_error", "_assume_error", "_clip", "_array_hint", "__all__", "__name__", "__doc__",
                "__builtins__", "__file__", "__spec__", "__loader__", "__package__", "__annotations__", "__dict__",
                "__class__")
#: `.ra` operator words: the grammar rejects them as names (E0013), so they are not cases.
RA_OPERATORS = {"and", "not", "or"}
NAMES = sorted((set(dir(builtins)) | set(keyword.kwlist) | set(keyword.softkwlist) | set(MODULE_NAMES))
               - RA_OPERATORS)

TRACE = [{"x": 1.5, "b": False, "k": 0}, {"x": 2.0, "b": True, "k": 1}, {"x": -0.0, "b": True, "k": -2},
         {"x": 7.25, "b": False, "k": -1}, {"x": 9.0, "b": False, "k": 2}, {"x": 0.1, "b": False, "k": 2}]


def source(automaton: str = "A", inp: str = "x", reward: str = "r", location: str = "L") -> str:
    """An automaton using each kind of name once: a numeric input in a rate, a bool in guards,
    an update, an end clause and an assume (whose error path calls ``int``/helpers)."""
    return f"""automaton {automaton} {{
    input {inp}: real in [-10, 10]
    input b: bool
    input k: int in [-2, 2]
    assume {inp} != 9 || k != 0
    reward {reward}, other
    objective {reward} + 2 * other
    sample every 0.5
    horizon 10
    initial location {location} {{ {reward}' == {inp}; other' == 1 }}
    location B {{ other' == -1 }}
    edge {location} -> B when b && {inp} > 1 do {reward} = {reward} + 1
    edge B -> {location} when !b && k >= 0
    at end when b do other = other + 3
}}"""


def bits(value: float) -> bytes:
    return struct.pack("<d", value)


def run_both(text: str, rename: dict[str, str] | None = None) -> None:
    """Generate, import and step the module; compare each step with the interpreter."""
    automaton = compile_text(text).raise_for_errors()
    code = generate_python(automaton, source_name="t.ra")
    module = types.ModuleType("generated_ra")
    exec(compile(code, "<generated_ra>", "exec"), module.__dict__)  # noqa: S102 - the code under test
    (class_name,) = module.__all__
    generated = getattr(module, class_name)()
    interpreter = RewardAutomaton(automaton)
    assert generated.name == automaton.name
    for values in TRACE:
        values = {(rename or {}).get(k, k): v for k, v in values.items()}
        assert bits(generated.step(values)) == bits(interpreter.step(values))
        assert (generated.location, generated.rewards) == (interpreter.location, interpreter.rewards)
    inp = (rename or {}).get("x", "x")
    for bad, message in [({inp: 9.0, "b": True, "k": 0}, "assume"), ({inp: 11.0, "b": True, "k": 0}, "outside"),
                         ({inp: 1.0, "b": True, "k": 0.5}, "integer"), ({inp: "1", "b": True, "k": 0}, "not a number"),
                         ({"b": True, "k": 0}, "missing"), ([], "map")]:
        for ra in (generated, interpreter):
            with pytest.raises(ValueError, match=message):
                ra.step(bad)  # type: ignore[arg-type]
    clipped = {inp: 12.0, "b": False, "k": 1}  # the clipping helper calls min and max: no class shadows them
    assert bits(generated.step(clipped, clip=True)) == bits(interpreter.step(clipped, clip=True))
    assert generated.clipped == interpreter.clipped == {inp: 1, "k": 0}
    last = {inp: 0.5, "b": True, "k": 1}
    assert bits(generated.end(last)) == bits(interpreter.end(last))
    assert generated.rewards == interpreter.rewards and generated.ended
    with pytest.raises(RuntimeError):
        generated.step(last)
    assert repr(generated).startswith(f"<{class_name} at ")


@pytest.mark.parametrize("name", NAMES)
def test_automaton_named_like_a_builtin_or_module_name(name: str) -> None:
    run_both(source(automaton=name))


@pytest.mark.parametrize("name", NAMES)
def test_input_reward_location_named_like_a_builtin_or_module_name(name: str) -> None:
    for text, rename in [(source(inp=name), {"x": name}), (source(reward=name), None),
                         (source(location=name), None)]:
        result = compile_text(text)
        if not result.ok:  # `.ra` keywords (input, reward ...) are not names there
            assert {d.code for d in result.diagnostics} <= {"E0001", "E0002", "E0013"}, result.diagnostics
            continue
        run_both(text, rename)


def test_only_the_ra_operator_words_are_refused_as_automaton_names() -> None:
    candidates = set(dir(builtins)) | set(keyword.kwlist) | set(keyword.softkwlist) | set(MODULE_NAMES)
    refused = {name for name in candidates if not compile_text(source(automaton=name)).ok}
    assert refused == RA_OPERATORS


def global_reads(code: str) -> set[str]:
    """Every name the module's code reads or binds at module level (symtable: globals of each scope)."""
    names: set[str] = set()

    def walk(table: symtable.SymbolTable) -> None:
        for symbol in table.get_symbols():
            if table.get_type() == "module" or symbol.is_global():
                names.add(symbol.get_name())
        for child in table.get_children():
            walk(child)

    walk(symtable.symtable(code, "<generated>", "exec"))
    return names


def test_every_global_name_of_the_module_is_reserved() -> None:
    # The reserved list is what keeps the class off the module's names: it must cover every name
    # the generated code reads, so a template change that uses a new builtin fails here.
    automaton = compile_text(source()).raise_for_errors()
    code = generate_python(automaton)
    dunders = {name for name in global_reads(code) if name.startswith("__") and name.endswith("__")}
    assert global_reads(code) - {"A"} - dunders <= RESERVED_NAMES


def test_compile_says_when_the_class_is_renamed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for name, said in [("float", "the class is `float_`: `float` is a Python keyword or a name the module itself uses"),
                       ("Driving", None)]:
        path = tmp_path / f"{name}.ra"
        path.write_text(source(automaton=name), encoding="utf-8")
        assert main(["compile", str(path), "--target", "python", "-o", str(tmp_path / "out.py")]) == 0
        err = capsys.readouterr().err
        assert (said in err) if said else "class" not in err, err
        assert python_class_name(name) == (name + "_" if said else name)
    assert python_class_name("__init__") == "init" and python_class_name("__") == "Automaton"


def test_the_module_imports_exactly_the_standard_modules_it_says() -> None:
    """MODULE_IMPORTS, which the output-name note reads, is the generated module's own imports."""
    code = generate_python(compile_text(source()).raise_for_errors())
    imported = set()
    for line in code.splitlines():
        words = line.split()
        if words[:1] == ["import"]:
            imported.add(words[1].split(".")[0])
        elif words[:1] == ["from"] and words[2:3] == ["import"]:
            imported.add(words[1].split(".")[0])
    assert imported == set(MODULE_IMPORTS)


@pytest.mark.parametrize(("file_name", "said"), [
    ("numbers.py", "`import numbers` gives this file instead, in your code and in every library that imports it, "
                   "the generated module included"),
    ("math.py", "the generated module included"),
    ("random.py", "`import random` gives this file instead, in your code and in every library that imports it; "),
    ("reward-fn.py", "`reward-fn.py` cannot be imported by name"),
    ("class.py", "`class.py` cannot be imported by name"),
    ("reward.txt", "`reward.txt` cannot be imported by name"),
    ("reward.py", None),
    ("Driving_2.py", None),
])
def test_compile_says_when_the_module_cannot_be_imported_by_its_name(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], file_name: str, said: str | None) -> None:
    """Regression: `rac compile -o numbers.py` wrote a module that, imported from its folder, imported
    itself (it imports `numbers`), and `-o reward-fn.py` one that `import` cannot name; both silently."""
    path = tmp_path / "a.ra"
    path.write_text(source(), encoding="utf-8")
    assert main(["compile", str(path), "--target", "python", "-o", str(tmp_path / file_name)]) == 0
    err = capsys.readouterr().err
    assert (said in err) if said else "note:" not in err, err
    assert (tmp_path / file_name).exists()  # a note, not a refusal
