"""The scenario model (docs/model.md): its data as int32 significands and its native functions.

- :mod:`rac.model.data`: :func:`build_model_data` turns a :class:`rac.model.commonroad.Scenario` and an
  :class:`rac.ir.ModelSpec` into :class:`ModelData` (every number a significand, Eq. (1)).
- :mod:`rac.model.native`: :class:`NativeModel`, the model's functions (``sense``, ``mindist``,
  ``collide``, ``offroad``, ``goal``, ``dist_goal``) in Python, bit for bit what the UPPAAL
  declarations from :mod:`rac.targets.uppaal.declarations` compute.

May import: core, ir.
"""

from rac.model.data import ActionData, ModelData, ModelRangeError, build_model_data, check_significands, max_significand
from rac.model.native import NO_OBSTACLE, NativeModel, State

__all__ = [
    "NO_OBSTACLE",
    "ActionData",
    "ModelData",
    "ModelRangeError",
    "NativeModel",
    "State",
    "build_model_data",
    "check_significands",
    "max_significand",
]
