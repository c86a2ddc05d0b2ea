"""rac.output.paths: FILE.out/COMMAND/ beside the file, or the folder the user chose."""

from __future__ import annotations

from pathlib import Path

from rac.output.paths import OUTPUT_CONVENTION, OUTPUT_SUFFIX, output_folder


def test_beside_the_file() -> None:
    assert output_folder(Path("examples/driving.ra"), "verify") == Path("examples/driving.out/verify")
    assert output_folder(Path("/tmp/a.b.ra"), "simulate") == Path("/tmp/a.b.out/simulate")


def test_chosen_folder_wins() -> None:
    assert output_folder(Path("driving.ra"), "verify", Path("elsewhere")) == Path("elsewhere")


def test_commands_get_distinct_folders() -> None:
    folders = {output_folder(Path("d.ra"), c) for c in ("verify", "simulate", "render")}
    assert len(folders) == 3 and all(f.parent == Path("d" + OUTPUT_SUFFIX) for f in folders)


def test_the_convention_in_words_names_the_suffix() -> None:
    assert OUTPUT_SUFFIX == ".out"
    assert "driving.out/verify/" in OUTPUT_CONVENTION and "-o/--out" in OUTPUT_CONVENTION
