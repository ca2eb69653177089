"""Blueprints: the committed blueprints/*.rbl match the code; names and errors."""

from __future__ import annotations

from pathlib import Path

import pytest

from studio.errors import StudioError
from studio.viz.blueprints import BLUEPRINTS, blueprint, describe, main, write_blueprints

REPO = Path(__file__).resolve().parents[2]


def test_committed_blueprints_match_the_code(tmp_path: Path) -> None:
    # .rbl files carry a fresh recording id, row ids and log times, so compare canonical descriptions
    write_blueprints(tmp_path, only_if_changed=False)
    for name in BLUEPRINTS:
        committed = REPO / "blueprints" / f"{name}.rbl"
        assert committed.exists(), f"{committed} missing: run python -m studio.viz.blueprints"
        assert describe(committed) == describe(tmp_path / f"{name}.rbl"), (
            f"{committed} is out of date: run python -m studio.viz.blueprints"
        )


def test_generator_is_stable_and_checks(tmp_path: Path) -> None:
    assert len(write_blueprints(tmp_path)) == 4
    assert write_blueprints(tmp_path) == []  # unchanged descriptions: nothing rewritten
    assert main(["--check", str(tmp_path)]) == 0
    (tmp_path / "compare.rbl").unlink()
    assert main(["--check", str(tmp_path)]) == 1


def test_describe_names_views() -> None:
    desc = describe(REPO / "blueprints" / "compare.rbl")
    assert desc[0] == {"application_id": "studio"}
    names = {next(iter(e["components"].get("ViewBlueprint:display_name", [None]))) for e in desc[1:]}
    assert {
        "per-frame FP / FN / ID switches",
        "disagreements (click to jump)",
        "panorama: tracks vs GT",
    } <= names


def test_unknown_blueprint_lists_names() -> None:
    with pytest.raises(StudioError, match="review, laser, calibration, compare"):
        blueprint("nope")
