"""Install from a wheel into a fresh venv: the wheel must carry the grammar, the stdlib and the templates.

The venv is plain (nothing from the base interpreter); rac comes from the wheel (``--no-deps``,
offline) and its dependencies (lark, numpy, jinja2) from this test process, through a ``.pth``
file. Site-packages of the new venv come first on its ``sys.path``, so ``import rac`` finds the
wheel's copy even where the dependencies' folder also holds an installed rac (as in CI).
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from conftest import REPOSITORY

DEPENDENCIES = ("lark", "numpy", "jinja2", "markupsafe")
IN_WHEEL = ("rac/__init__.py", "rac/grammar/rac.lark", "rac/stdlib/driving.ra",
            *(f"rac/stdlib/{name}.ra" for name in ("safe_distance", "speed_limit", "goal_window", "lane_change")),
            "rac/targets/templates/python_module.py.j2", "rac/targets/uppaal/templates/model.xml.j2")


def child_env() -> dict[str, str]:
    """The environment minus whatever could make a child Python find rac outside its own venv."""
    drop = {"PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV", "PYTHONSTARTUP", "PYTHONUSERBASE"}
    return {k: v for k, v in os.environ.items() if k not in drop} | {"PIP_DISABLE_PIP_VERSION_CHECK": "1",
                                                                        "PYTHONNOUSERSITE": "1"}


def run(*command: str | Path, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    done = subprocess.run([str(part) for part in command], cwd=cwd, env=child_env(), capture_output=True,
                          text=True, timeout=timeout, check=False)
    assert done.returncode == 0, f"{' '.join(map(str, command))} failed:\n{done.stdout}\n{done.stderr}"
    return done


def build_wheel(out: Path) -> Path:
    """``python -m build --wheel`` of the checkout; offline when hatchling is already installed here."""
    if importlib.util.find_spec("build") is None:
        pytest.skip("the `build` package is not installed (it is in the `test` extra)")
    isolation = [] if importlib.util.find_spec("hatchling") is None else ["--no-isolation"]
    run(sys.executable, "-m", "build", "--wheel", *isolation, "--outdir", out, REPOSITORY, cwd=out.parent)
    [wheel] = out.glob("rac-*.whl")
    return wheel


def test_install_from_wheel(tmp_path: Path) -> None:
    wheel = build_wheel(tmp_path / "dist")
    names = set(zipfile.ZipFile(wheel).namelist())
    for name in IN_WHEEL:
        assert name in names, f"{name} is missing from {wheel.name}"
    assert not any(name.startswith(("tests/", "benchmarks/")) for name in names)

    venv = tmp_path / "venv"
    run(sys.executable, "-m", "venv", venv, cwd=tmp_path)
    bin_dir = venv / ("Scripts" if os.name == "nt" else "bin")
    python = bin_dir / "python"
    run(python, "-m", "pip", "install", "--quiet", "--no-deps", "--no-index", wheel, cwd=tmp_path)
    purelib = Path(run(python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])",
                       cwd=tmp_path).stdout.strip()).resolve()
    folders = {str(Path(importlib.util.find_spec(dep).origin).resolve().parent.parent)  # type: ignore[arg-type]
               for dep in DEPENDENCIES}
    (purelib / "rac_test_dependencies.pth").write_text("\n".join(sorted(folders)) + "\n", encoding="utf-8")

    located = run(python, "-c", "import rac, rac.lang.resources; print(rac.__file__); "
                  "print(rac.lang.resources.stdlib_file('driving.ra'))", cwd=tmp_path).stdout.splitlines()
    package, driving = (Path(line).resolve() for line in located)
    assert package.is_relative_to(purelib), f"rac was imported from {package}, not from the wheel"
    assert not package.is_relative_to(REPOSITORY)
    assert driving.is_relative_to(purelib), f"the stdlib was found at {driving}, not inside the installed package"

    checked = run(bin_dir / "rac", "check", driving, cwd=tmp_path)
    assert "P2 holds" in checked.stdout, checked.stdout
    version = run(bin_dir / "rac", "--version", cwd=tmp_path)
    assert version.stdout.startswith("rac ")

    out = tmp_path / "driving_ra.py"
    run(bin_dir / "rac", "compile", driving, "--target", "python", "-o", out, cwd=tmp_path)
    assert "class Driving" in out.read_text(encoding="utf-8")


def test_the_rl_extras_tensorboard_shows_its_logs_beside_numpy_2_and_commonroad() -> None:
    # the extra pinned tensorboard < 2.17, whose viewer ends at its start beside numpy 2 (`np.string_` was removed,
    # in its hparams plugin) and without setuptools' pkg_resources (removed in setuptools 82): `tensorboard --logdir`
    # could not show the logs of configure(folder, ["tensorboard"]) that docs/python.md writes
    import tomllib

    from packaging.requirements import Requirement

    extra = tomllib.loads((REPOSITORY / "pyproject.toml").read_text(encoding="utf-8"))["project"][
        "optional-dependencies"]["rl"]
    wanted = {(requirement := Requirement(text)).name: requirement.specifier for text in extra}
    tensorboard, setuptools = wanted["tensorboard"], wanted.get("setuptools")
    assert not tensorboard.contains("2.16.2") and tensorboard.contains("2.17.1") and tensorboard.contains("2.20.0")
    assert not tensorboard.contains("2.21.0")  # needs protobuf >= 5, which commonroad-io's pin (3.20.2) excludes
    assert setuptools is not None and not setuptools.contains("82.0.0") and setuptools.contains("81.0.0")
    installed = importlib.util.find_spec("tensorboard")
    if installed is not None:  # where the extra is installed as it says: the viewer's imports that failed
        from importlib.metadata import version

        if tensorboard.contains(version("tensorboard")) and setuptools.contains(version("setuptools")):
            importlib.import_module("tensorboard.plugins.hparams.metadata")
            importlib.import_module("tensorboard.default")
