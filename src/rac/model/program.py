"""A checked automaton with its scenario model: :class:`CheckedProgram`, what the engine, the targets,
``rac verify`` and the learning code read of a checked file.

The checker makes it (:meth:`rac.compiler.CompileResult.checked`) from the scenario it loaded once
through :func:`rac.model.checks.load`, the one loader of a `model` block's scenario. A consumer
handed a bare :class:`rac.ir.Automaton` asks the same loader (:meth:`CheckedProgram.of`), which
honours the block's `planning_problem` exactly as ``rac check`` does: a file with several planning
problems and none chosen is a :class:`rac.model.commonroad.PlanningProblemError` (E0715), never a
silently chosen one.

The class lives here, not in :mod:`rac.compiler`, because the engine and the targets may import
``model`` but not the compiler (docs/architecture.md, "The layers").
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING

from rac import ir
from rac.model.checks import load
from rac.model.data import build_model_data

if TYPE_CHECKING:
    from rac.model.commonroad import Scenario
    from rac.model.data import ModelData

__all__ = ["CheckedProgram", "ProgramSource", "program_of"]


@dataclass(frozen=True, eq=False)
class CheckedProgram:
    """An automaton that passed the checks (its IR), with the model's data and the scenario of its
    `model` block (both None without one). ``eq=False``: two programs are the same object or not."""

    automaton: ir.Automaton
    #: The model's data at the block's base and exponent (None without a `model` block).
    model_data: ModelData | None = None
    #: The scenario the data was built from (None without a `model` block).
    scenario: Scenario | None = None

    @classmethod
    def of(cls, automaton: ir.Automaton, *, max_bytes: int | None = None) -> CheckedProgram:
        """``automaton`` with the scenario of its `model` block loaded by :func:`rac.model.checks.load`
        (cached; ``max_bytes`` as there) and the model's data built from it; without a `model` block,
        the automaton alone. Raises :class:`rac.model.commonroad.ScenarioError` (a
        :class:`~rac.model.commonroad.PlanningProblemError` where ``rac check`` reports E0715) or
        :class:`rac.model.data.ModelRangeError` when the scenario cannot be loaded or represented."""
        spec = automaton.model
        if spec is None:
            return cls(automaton)

        scenario = load(spec, max_bytes=max_bytes)
        return cls(automaton, build_model_data(scenario, spec), scenario)

    @property
    def data(self) -> ModelData:
        """The model's data; ``ValueError`` without a `model` block."""
        if self.model_data is None:
            raise ValueError(f"`{self.automaton.name}` has no `model` block: there is no scenario model")
        return self.model_data


class ProgramSource(ABC):
    """What can give a :class:`CheckedProgram`: :class:`rac.compiler.CompileResult` is one. The engine
    and the targets accept it by this name, since they may not import the compiler."""

    @abstractmethod
    def checked(self) -> CheckedProgram:
        """The checked program; :class:`rac.core.diagnostics.CheckError` when there is none."""


def program_of(source: ProgramSource | CheckedProgram | ir.Automaton) -> CheckedProgram:
    """The :class:`CheckedProgram` of ``source``: itself, the one its source made, or (an automaton) the
    one :meth:`CheckedProgram.of` loads."""
    if isinstance(source, CheckedProgram):
        return source
    if isinstance(source, ProgramSource):
        return source.checked()
    if isinstance(source, ir.Automaton):
        return CheckedProgram.of(source)
    raise TypeError(f"expected a CompileResult, a CheckedProgram or an ir.Automaton, not {type(source).__name__}")
