"""Atomic writers: all or nothing, and files get the usual permissions."""

from __future__ import annotations

import os
import stat

import pytest

from studio.atomic import atomic_dir, atomic_write_text, out_file
from studio.errors import StudioError


def test_file_mode_follows_umask(tmp_path) -> None:
    old = os.umask(0o022)
    try:
        atomic_write_text(tmp_path / "a.txt", "x")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "a.txt").stat().st_mode) == 0o644
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_atomic_dir_keeps_old_content_on_failure(tmp_path) -> None:
    out = tmp_path / "run"
    with atomic_dir(out, outputs=("labels.yaml",)) as d:
        (d / "labels.yaml").write_text("old")

    def half_written() -> None:
        with atomic_dir(out, outputs=("labels.yaml",)) as d:
            (d / "labels.yaml").write_text("half")
            raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        half_written()
    assert (out / "labels.yaml").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    with atomic_dir(out, outputs=("labels.yaml",)) as d:
        (d / "labels.yaml").write_text("new")
    assert (out / "labels.yaml").read_text() == "new"


def test_atomic_dir_replaces_only_an_earlier_output(tmp_path) -> None:
    """A directory of the user's files, or an earlier output someone added to (annotations), is never
    replaced: one clear error, before and after the work, and everything stays as it was."""
    outputs = ("run.json", "labels.yaml")
    out = tmp_path / "run"
    with atomic_dir(out, outputs=outputs) as d:
        (d / "run.json").write_text("{}")
    with atomic_dir(out, outputs=outputs) as d:  # an earlier output: replaced
        (d / "run.json").write_text('{"again": 1}')
        (d / "labels.yaml").write_text("x")
    assert (out / "labels.yaml").is_file()
    (out / "annotations").mkdir()
    (out / "annotations" / "corrections.jsonl").write_text("keep")
    with pytest.raises(StudioError, match="annotations"), atomic_dir(out, outputs=outputs):
        pytest.fail("must not start")
    data = tmp_path / "data"
    data.mkdir()
    (data / "my.bag").write_text("bag")
    with pytest.raises(StudioError, match=r"my\.bag"), atomic_dir(data, outputs=outputs):
        pytest.fail("must not start")
    (tmp_path / "file").write_text("f")
    with pytest.raises(StudioError, match="not a directory"), atomic_dir(tmp_path / "file", outputs=outputs):
        pytest.fail("must not start")
    # annotations made while the run was being built: the new run is thrown away, the old one kept
    out2 = tmp_path / "run2"
    with atomic_dir(out2, outputs=outputs) as d:
        (d / "run.json").write_text("old")

    def annotated_meanwhile() -> None:
        with atomic_dir(out2, outputs=outputs) as d:
            (d / "run.json").write_text("new")
            (out2 / "annotations").mkdir()

    with pytest.raises(StudioError, match="annotations"):
        annotated_meanwhile()
    assert (out2 / "run.json").read_text() == "old"
    assert (out / "annotations" / "corrections.jsonl").read_text() == "keep"
    assert (data / "my.bag").read_text() == "bag"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_out_file_names_what_is_wrong_before_any_work(tmp_path) -> None:
    assert out_file(None, "--json") is None
    assert (
        out_file(tmp_path / "new" / "deeper" / "m.json", "--json") == tmp_path / "new" / "deeper" / "m.json"
    )
    assert not (tmp_path / "new").exists()  # checked, not made
    with pytest.raises(StudioError, match=r"^--json .*: is a directory, expected a file name$"):
        out_file(tmp_path, "--json")
    (tmp_path / "f").write_text("")
    with pytest.raises(StudioError, match=r"^--out .*: .*/f is not a folder$"):
        out_file(tmp_path / "f" / "x.csv", "--out")
    if os.geteuid() != 0:  # root may write anywhere
        ro = tmp_path / "ro"
        ro.mkdir(mode=0o500)
        with pytest.raises(StudioError, match="cannot write in"):
            out_file(ro / "x.csv", "--out")
    (tmp_path / "in.jsonl").write_text("ground truth")
    with pytest.raises(StudioError, match=r"^--json .*: is an input of this command"):
        out_file(tmp_path / "." / "in.jsonl", "--json", inputs=[None, tmp_path / "in.jsonl"])
    assert (tmp_path / "in.jsonl").read_text() == "ground truth"


def test_an_earlier_output_with_a_file_added_inside_or_edited_is_kept(tmp_path) -> None:
    """Only the top-level names were checked once: a file the user put in an output's sub-folder (the
    exported frames) was deleted with it, and so were edits to its files."""
    outputs = ("run.json", "frames", "DATASET.md", "metrics.json")
    out = tmp_path / "run"

    def write() -> None:
        with atomic_dir(out, outputs=outputs) as d:
            (d / "run.json").write_text("{}")
            (d / "frames").mkdir()
            (d / "frames" / "000000.jpg").write_bytes(b"jpeg")
            (d / "DATASET.md").write_text("card")

    write()
    (out / "metrics.json").write_text("written later by the same command")
    write()  # an earlier output, with a file of its own written after it: replaced
    assert not (out / "metrics.json").exists()
    (out / "frames" / "my_labels.xml").write_text("mine")
    with pytest.raises(StudioError, match=r"frames/my_labels\.xml \(added\)"):
        write()
    assert (out / "frames" / "my_labels.xml").read_text() == "mine"
    (out / "frames" / "my_labels.xml").unlink()
    (out / "DATASET.md").write_text("card, with my notes")
    with pytest.raises(StudioError, match=r"DATASET\.md \(edited\)"):
        write()
    assert (out / "DATASET.md").read_text() == "card, with my notes"


def test_a_users_folder_beside_the_output_is_not_touched(tmp_path) -> None:
    outputs = ("run.json",)
    out = tmp_path / "run"
    with atomic_dir(out, outputs=outputs) as d:
        (d / "run.json").write_text("{}")
    (tmp_path / ".run.old").mkdir()
    (tmp_path / ".run.old" / "important.txt").write_text("x")
    with atomic_dir(out, outputs=outputs) as d:  # replaces the earlier output
        (d / "run.json").write_text("{}")
    assert (tmp_path / ".run.old" / "important.txt").read_text() == "x"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".run.old", "run"]


def test_an_output_whose_folder_is_a_file_is_one_error_before_any_work(tmp_path) -> None:
    (tmp_path / "afile").write_text("f")
    with pytest.raises(StudioError, match=r"afile is not a folder"), atomic_dir(tmp_path / "afile" / "run"):
        pytest.fail("must not start")
