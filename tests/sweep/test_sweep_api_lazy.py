"""rac.sweep re-exports rac.sweep.api on first use: the names are the API's, and importing the task
list (rac.sweep.kinds, which rac's parser reads) does not load the API."""

from __future__ import annotations

import subprocess
import sys

import pytest

import rac.sweep
from rac.sweep import api


def test_the_package_names_are_the_apis() -> None:
    for name in rac.sweep.__all__:
        assert getattr(rac.sweep, name) is getattr(api, name)
    assert set(rac.sweep.__all__) <= set(dir(rac.sweep))
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        rac.sweep.nothing  # noqa: B018


def test_the_task_list_alone_does_not_load_the_api() -> None:
    code = "import sys, rac.sweep.kinds; print('rac.sweep.api' in sys.modules, 'rac.ir' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.stdout.split() == ["False", "False"], done.stderr
