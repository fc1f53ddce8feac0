"""What ``stack`` refuses or warns of before its first pass, and how its flags describe the passes
(sarmitsuba/cli_stack.py, sarmitsuba/stack.py, docs/physics.md (TS1)).

The truths are the test's own: the even baselines ``linspace(-span / 2, span / 2, N)`` of the
guide's ``--span M --passes N``; a disk that has 10 GiB free for a stack of urban's 1000 passes
(each pass writes some 20 MiB: 2.8 MB of raw data, 7.7 MB of image.npz, 11.6 MB of image.exr);
a folder the test rendered into. The disk estimate itself is checked against the files of a
rendered stack in tests/test_stack_tomography.py.
"""
from __future__ import annotations

import math
import shutil
from collections import namedtuple

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (libLLVM, variant)
from sarmitsuba import stack as stack_module
from sarmitsuba.cli import build_parser, main
from sarmitsuba.cli_stack import stack_description
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.scene.baseline import stack_baselines
from sarmitsuba.scene.loader import load_scene

Usage = namedtuple("Usage", "total used free")
GIB = 2**30
#: urban --span 5 --passes 1000, as the issue gives it
BIG = ["stack", "urban", "--span", "5", "--passes", "1000", "--no-progress"]


@pytest.mark.parametrize("incidence", [30.0, 55.0])
def test_span_and_passes_are_even_and_random_baselines_are_not(incidence):
    """``--span 6 --passes 7``: the passes at -3, -2, ..., 3 m of perpendicular baseline; with
    ``--random-baselines 4`` the two ends kept, the five between them not evenly spaced, the same
    for the same seed (uniform and random swapped fails both)."""
    params = load_scene("trihedral", {"incidence_angle": incidence}).params
    parser = build_parser()
    even = stack_baselines(params, **stack_description(parser.parse_args(
        ["stack", "trihedral", "--span", "6", "--passes", "7", "--out", "x"])))
    assert even.perpendicular == pytest.approx(np.arange(-3.0, 3.5, 1.0), abs=1e-5)
    argv = ["stack", "trihedral", "--span", "6", "--passes", "7", "--random-baselines", "4", "--out", "x"]
    drawn = stack_baselines(params, **stack_description(parser.parse_args(argv)))
    again = stack_baselines(params, **stack_description(parser.parse_args(argv)))
    assert drawn.perpendicular[[0, -1]] == pytest.approx([-3.0, 3.0], abs=1e-5)
    assert np.max(np.abs(drawn.perpendicular - np.arange(-3.0, 3.5, 1.0))) > 0.05
    assert np.array_equal(drawn.perpendicular, again.perpendicular)


def test_a_negative_seed_is_refused_by_its_flag_and_in_python(capsys):
    """``--random-baselines -1`` ended in numpy's traceback; now argparse's one line naming the flag
    and the range (exit 2), and ``seed = -1`` a ParameterError in Python."""
    with pytest.raises(SystemExit) as stop:
        main(["stack", "trihedral", "--span", "2", "--passes", "4", "--random-baselines", "-1", "--out", "x"])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and "--random-baselines" in err and ">= 0" in err and "Traceback" not in err
    params = load_scene("trihedral").params
    with pytest.raises(ParameterError, match="seed = -1"):
        stack_baselines(params, span=2.0, count=4, spacing="random", seed=-1)


@pytest.mark.parametrize("argv, words", [
    (["--span", "2"], "--passes is missing"),
    (["--passes", "4"], "--span is missing"),
    (["--span", "2", "--passes", "4", "--baselines", "0,1,2"], "both describe the passes"),
    (["--baselines", "0,1,2", "--random-baselines", "3"], "--random-baselines places the passes within --span"),
    (["--span", "2", "--passes", "4", "--set", "track_offset=0,0,1"], "--set track_offset=0,0,1"),
])
def test_flags_that_do_not_describe_one_stack_are_refused(tmp_path, capsys, argv, words):
    """Nothing silently ignored (``--baselines`` beside ``--span``, ``--random-baselines`` beside
    ``--baselines``): one line naming the flags, exit 2, no folder."""
    code = main(["stack", "trihedral", *argv, "--out", str(tmp_path / "s")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("error:") == 1 and words in err, err
    assert not (tmp_path / "s").exists()


def test_a_render_folder_is_refused_as_the_stack_folder(tmp_path, capsys):
    """``stack --out`` into a render's folder would write the passes beside its files; refused,
    the render's files as they were."""
    render = tmp_path / "render"
    assert main(["render", "trihedral", "--pulses", "16", "--out", str(render), "--no-progress"]) == 0
    before = sorted(p.name for p in render.iterdir())
    capsys.readouterr()
    assert main(["stack", "trihedral", "--span", "1", "--passes", "3", "--out", str(render)]) == 2
    err = capsys.readouterr().err
    assert err.count("error:") == 1 and "--out" in err and "render folder" in err and "out_dir" not in err, err
    assert sorted(p.name for p in render.iterdir()) == before


def test_a_stack_that_does_not_fit_on_the_disk_is_refused_before_anything_is_written(tmp_path, capsys, monkeypatch):
    """urban's 1000 passes need over 20 GiB (each pass 2.8 MB of raw data and 19 MB of images);
    with 10 GiB free: exit 2, naming the flag, the sizes and the free space; no folder."""
    monkeypatch.setattr(stack_module.shutil, "disk_usage", lambda path: Usage(100 * GIB, 90 * GIB, 10 * GIB))

    def first_pass(*args, **kwargs):
        raise AssertionError("a pass started")

    monkeypatch.setattr(stack_module, "render_pass", first_pass)
    out = tmp_path / "big"
    assert main([*BIG, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("error:") == 1 and "--out" in err and "10.0 GiB free" in err and "out_dir" not in err, err
    needed = float(err.split("would write about ")[1].split(" GiB")[0])
    assert 1000 * 20e6 / GIB < needed < 1000 * 25e6 / GIB
    assert not out.exists()


def test_a_large_stack_warns_of_its_time_and_disk_before_its_first_pass(tmp_path, capsys, monkeypatch):
    """With room on the disk, urban's 1000 passes start with one warning line giving the hours
    and the GiB (the first pass is stopped here: nothing is rendered)."""
    monkeypatch.setattr(stack_module.shutil, "disk_usage", lambda path: Usage(1000 * GIB, 0, 1000 * GIB))

    def first_pass(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(stack_module, "render_pass", first_pass)
    assert main([*BIG, "--out", str(tmp_path / "big")]) == 130
    err = capsys.readouterr().err
    warning = [line for line in err.splitlines() if line.startswith("warning: a large stack")]
    assert len(warning) == 1 and "1000 passes" in warning[0] and "GiB" in warning[0], err
    seconds = float(warning[0].split("about ")[1].split(" s")[0].replace(",", ""))
    assert seconds > stack_module.LARGE_STACK_SECONDS and math.isfinite(seconds)
    assert not (tmp_path / "big" / "pass-00").exists()


def test_disk_usage_is_read_where_the_folder_will_be(tmp_path, monkeypatch):
    """The free space is that of the nearest existing folder above ``--out`` (its file system)."""
    seen = []
    real = shutil.disk_usage

    def spy(path):
        seen.append(path)
        return real(path)

    monkeypatch.setattr(stack_module.shutil, "disk_usage", spy)
    monkeypatch.setattr(stack_module, "render_pass", lambda *a, **k: (_ for _ in ()).throw(KeyboardInterrupt))
    with pytest.raises(KeyboardInterrupt):
        stack_module.render_stack("trihedral", tmp_path / "a" / "b", span=1.0, count=3, progress=False,
                                  sensor_overrides={"n_pulses": 16})
    assert seen == [tmp_path]
