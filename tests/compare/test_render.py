"""``tippetop render``: the MP4s decode, the replays put the body where the engines say, bad input
ends in one line with no file left, and the simulation never touches OpenGL.

Videos are tiny (160x120, 20 fps, real time, 0.5 s simulated: 11 frames) and MuJoCo steps at
1e-4 s, so the file runs in seconds. They need an offscreen OpenGL backend (Debian's libegl1
libopengl0 libgl1-mesa-dri, or libosmesa6), which CI installs.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import textwrap
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import imageio.v3 as iio
import mujoco
import numpy as np
import pytest

from tippetop.compare import cli
from tippetop.compare.commands import render as render_command
from tippetop.compare.presentation import video as pvideo
from tippetop.compare.running.engines import run_engine
from tippetop.compare.running.options import RunOptions
from tippetop.compare.studies import render
from tippetop.models.errors import TippetopError
from tippetop.models.frames import quat_to_mat
from tippetop.models.scene import load_scene
from tippetop.mujoco_runner import gl
from tippetop.mujoco_runner.model import TopModel, TopModelWarning

if TYPE_CHECKING:
    from tippetop.mujoco_runner.inset import InsetLayout
    from tippetop.mujoco_runner.poses import Track

ROOT = Path(__file__).resolve().parents[2]
SHORT = ("run.t_end_s=0.5", "mujoco.timestep_s=1e-4")
FPS, SPEED, W, H = 20.0, 1.0, 160, 120
N_FRAMES = 11  # t_k = k * speed / fps = 0, 0.05, ..., 0.5 s


def _frames(path: Path) -> np.ndarray:
    return iio.imread(path, index=None, plugin="FFMPEG")


@pytest.fixture(scope="module")
def backend() -> str:
    """The backend the render command picks here (MUJOCO_GL is left as it was)."""
    return gl.choose_gl_backend()


@pytest.fixture(scope="module")
def videos(tmp_path_factory: pytest.TempPathFactory, backend: str) -> dict[str, Path]:
    """One short MuJoCo video and one side-by-side video of Fig. 3."""
    folder = tmp_path_factory.mktemp("videos")
    scene = load_scene("fig3", list(SHORT))
    out = {}
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MUJOCO_GL", backend)  # restored afterwards; render_scene writes it
        for engine in ("mujoco", "both"):
            engines = ("mujoco", "ode") if engine == "both" else (engine,)
            res = render.render_scene(scene, folder / f"{engine}.mp4", engines=engines,
                                      video=render.VideoOptions(fps=FPS, speed=SPEED,
                                                                size=(W, H)),
                                      run=RunOptions(progress=False))
            assert res.n_frames == N_FRAMES and res.backend == backend
            out[engine] = res.path
    return out


def test_frame_times_and_sizes() -> None:
    assert pvideo.frame_count(0.5, FPS, SPEED) == N_FRAMES
    # the default: 8 s at quarter speed and 30 fps is 32 s of video
    assert pvideo.frame_count(8.0, 30.0, 0.25) == 961
    assert pvideo.parse_size("641x481") == (640, 480)  # yuv420p needs even sides
    # 240 frames show 239 intervals: 8 s at 15 fps fits at 8 * 15 / 239, not 8 * 15 / 240
    assert pvideo.frame_count(8.0, 15.0, 8.0 * 15.0 / 240) == 241
    assert pvideo.frame_count(8.0, 15.0, pvideo.speed_to_fit(8.0, 15.0, 240)) == 240
    assert pvideo.speed_to_fit(8.0, 15.0, 240, min_speed=1.0) == 1.0


def test_mujoco_video_decodes_with_expected_frames_and_size(videos: dict[str, Path]) -> None:
    frames = _frames(videos["mujoco"])
    assert frames.shape == (N_FRAMES, H, W, 3)
    assert frames.dtype == np.uint8
    # the top spins at ~100 rad/s (0.05 s of simulated time between frames), the text changes:
    # every frame differs from the one before
    steps = np.abs(np.diff(frames.astype(int), axis=0)).mean(axis=(1, 2, 3))
    assert np.all(steps > 1.0), steps


def test_both_is_two_panels_on_one_time_base(videos: dict[str, Path]) -> None:
    from tippetop.mujoco_runner.inset import inset_layout

    frames = _frames(videos["both"])
    assert frames.shape == (N_FRAMES, H, 2 * W, 3)
    left, right = frames[:, :, :W].astype(int), frames[:, :, W:].astype(int)
    # Same camera, same times, and the engines agree to ~1e-4 rad over 0.5 s: below the text
    # box, in the middle of each panel (the comparison inset straddles the seam) the two
    # panels are nearly the same picture, while each changes from frame to frame.
    x0, _, x1, _ = inset_layout(W, H).box
    rows, cols = slice(H // 3, H), slice(x1 - W, x0)  # clear of the inset in both panels
    assert x0 - (x1 - W) >= W // 6
    between_panels = np.abs(left[:, rows, cols] - right[:, rows, cols]).mean()
    over_time = np.abs(left[-1, rows, cols] - left[0, rows, cols]).mean()
    assert between_panels < 0.25 * over_time, (between_panels, over_time)


def test_both_has_the_comparison_inset_and_nothing_else_added(
        videos: dict[str, Path]) -> None:
    """The left panel of ``both`` is the MuJoCo-only video, but for the inset's box."""
    from tippetop.mujoco_runner.inset import inset_layout

    both = _frames(videos["both"])[:, :, :W].astype(int)
    alone = _frames(videos["mujoco"]).astype(int)
    x0, y0, _, y1 = inset_layout(W, H).box
    inside = np.abs(both[:, y0:y1, x0:W] - alone[:, y0:y1, x0:W]).mean()
    outside = np.abs(both[:, :y0] - alone[:, :y0]).mean()
    assert outside < 2.0, outside  # H.264 noise only
    assert inside > 20.0, inside  # the darkened box, its text and the plot


def _pose_check(scene, engine: str, paper_frame: bool) -> None:
    """Replay the engine's table; the drawn body must sit where the table's pose says."""
    from tippetop.mujoco_runner import drawn_model, poses, video

    table = run_engine(scene, engine, progress=False).table
    top_model = drawn_model.render_model(scene.top, scene.top_mjcf, W, H)
    track = poses.Track.from_table(table, top_model, label=engine, paper_frame=paper_frame)
    times = video.frame_times(N_FRAMES, FPS, SPEED)
    samples = track.at(times)
    data = mujoco.MjData(top_model.model)
    a = top_model.top.a_m
    ball = top_model.ball_geom_id
    for k in (0, 3, 7, 10):  # frame times on the table's 1 ms grid
        row = table.iloc[int(np.argmin(np.abs(table["t"].to_numpy() - times[k])))]
        assert abs(row["t"] - times[k]) < 1e-12
        poses.set_pose(top_model, data, samples[k].qpos)
        q = np.array(row[["qw", "qx", "qy", "qz"]], dtype=float)
        q = q / np.linalg.norm(q)
        rot = quat_to_mat(q)
        com = np.array(row[["x", "y", "z"]], dtype=float)
        k_axis = rot[:, 2] if paper_frame else rot @ top_model.axis_body
        xmat = data.xmat[top_model.body_id].reshape(3, 3)
        # the sphere's centre S = O + a k, the symmetry axis and the centre of mass
        np.testing.assert_allclose(data.geom_xpos[ball], com + a * k_axis, rtol=0, atol=1e-9)
        np.testing.assert_allclose(xmat @ top_model.axis_body, k_axis, rtol=0, atol=1e-9)
        np.testing.assert_allclose(data.xipos[top_model.body_id], com, rtol=0, atol=1e-9)
        if np.allclose(top_model.paper_from_body_quat, [1, 0, 0, 0]) and not np.any(
                top_model.centre_body_m):
            # make_mjcf tops: body frame = the paper's, body origin = S; pose = (S, q) exactly
            xquat = data.xquat[top_model.body_id]
            assert min(np.abs(xquat - q).max(), np.abs(xquat + q).max()) < 1e-9
            np.testing.assert_allclose(data.xpos[top_model.body_id], com + a * rot[:, 2],
                                       rtol=0, atol=1e-9)


def test_ode_replay_puts_the_body_at_the_ode_pose() -> None:
    _pose_check(load_scene("fig3", list(SHORT)), "ode", paper_frame=True)


def test_mujoco_replay_puts_the_body_at_the_mujoco_pose() -> None:
    _pose_check(load_scene("fig3", list(SHORT)), "mujoco", paper_frame=False)


def test_ode_replay_in_an_mjcf_whose_body_frame_is_not_the_papers(tmp_path: Path) -> None:
    """Body origin at the centre of mass, symmetry axis along the body's -y (C on y)."""
    top = load_scene("fig3").top
    xml = f"""<mujoco><option gravity="0 0 {-top.g_mps2!r}"/><worldbody>
      <body pos="0 0 0.1"><freejoint/>
        <inertial pos="0 0 0" mass="{top.M_kg!r}"
                  diaginertia="{top.A_kgm2!r} {top.C_kgm2 * 1.05!r} {top.A_kgm2!r}"/>
        <geom type="sphere" size="{top.R_m!r}" pos="0 {-top.a_m!r} 0" condim="1"/>
      </body></worldbody></mujoco>"""
    path = tmp_path / "top.xml"
    path.write_text(xml)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TopModelWarning)  # origin off the ball's centre
        scene = load_scene("fig3", [*SHORT, f"top.mjcf={json.dumps(str(path))}"])
        _pose_check(scene, "ode", paper_frame=True)


def test_interpolation_between_samples_is_on_the_way() -> None:
    from tippetop.mujoco_runner import drawn_model, poses

    scene = load_scene("fig3", list(SHORT))
    table = run_engine(scene, "ode", progress=False).table
    top_model = drawn_model.render_model(scene.top, scene.top_mjcf, W, H)
    track = poses.Track.from_table(table, top_model, label="ode", paper_frame=True)
    t0, t1 = table["t"].iloc[100], table["t"].iloc[101]
    a, mid, b = track.at([t0, 0.5 * (t0 + t1), t1])
    # one 1 ms sample interval turns the top by ~0.1 rad: the midpoint is halfway (slerp)
    angle = lambda p, q: 2 * np.arccos(min(1.0, abs(float(np.dot(p[3:], q[3:])))))  # noqa: E731
    assert angle(a.qpos, b.qpos) > 0.05
    assert abs(angle(a.qpos, mid.qpos) - angle(mid.qpos, b.qpos)) < 1e-9
    np.testing.assert_allclose(mid.qpos[:3], 0.5 * (a.qpos[:3] + b.qpos[:3]), atol=1e-6)
    assert mid.theta == pytest.approx(0.5 * (a.theta + b.theta))
    assert not mid.ended and track.at([0.6])[0].ended


# ---------------------------------------------------------------- the comparison inset, the camera
def _synthetic_track(top_model: TopModel, label: str,
                     theta_of_t: Callable[[np.ndarray], np.ndarray],
                     t_end_s: float = 1.0) -> Track:
    """A track whose axis tilts about x by theta(t), the ball's centre fixed at (0, 0, R)."""
    from tippetop.mujoco_runner import poses

    t = np.linspace(0.0, t_end_s, 101)
    theta = theta_of_t(t)
    zero = np.zeros_like(t)
    quat = np.stack([np.cos(theta / 2), np.sin(theta / 2), zero, zero], axis=1)
    k = np.stack([zero, -np.sin(theta), np.cos(theta)], axis=1)  # R_x(theta) e_z
    com = np.array([0.0, 0.0, top_model.top.R_m]) - top_model.top.a_m * k
    return poses.Track(label=label, t_s=t, com_m=com, quat=quat, theta=theta,
                       n=np.full_like(t, 100.0), top_model=top_model)


def _ramp(t: np.ndarray) -> np.ndarray:
    return 0.1 + 2.9 * t


@pytest.fixture(scope="module")
def inset_tracks() -> dict[str, Track]:
    from tippetop.mujoco_runner import drawn_model

    top_model = drawn_model.render_model(load_scene("fig3").top, None, 320, 240)
    return {"mujoco": _synthetic_track(top_model, "MuJoCo", _ramp),
            "same": _synthetic_track(top_model, "reference ODE", _ramp),
            "off": _synthetic_track(top_model, "reference ODE", lambda t: _ramp(t) - 0.5)}


def _draw_inset(first: Track, second: Track, t: float) -> tuple[np.ndarray, InsetLayout]:
    """The inset of (first, second) at time t on a flat grey 2 x 320 x 240 frame."""
    from tippetop.mujoco_runner.inset import ThetaInset

    inset = ThetaInset([first, second], 1.0, 320, 240)
    frame = np.full((240, 640, 3), 128, dtype=np.uint8)
    inset.draw(frame, [first.at([t])[0], second.at([t])[0]])
    return frame, inset.layout


def test_inset_readout_changes_with_delta_theta_only(inset_tracks: dict[str, Track]) -> None:
    same, layout = _draw_inset(inset_tracks["mujoco"], inset_tracks["same"], 0.5)
    off, _ = _draw_inset(inset_tracks["mujoco"], inset_tracks["off"], 0.5)
    x0, y0, x1, y1 = layout.box
    px0, py0, px1, py1 = layout.plot
    outside = np.ones(same.shape[:2], bool)
    outside[y0:y1, x0:x1] = False
    assert np.all(same[outside] == 128) and np.all(off[outside] == 128)  # only in its box
    line = (py0 - y0) // 2  # two lines of text above the plot: the readout, the legend
    readout = (slice(y0, y0 + line), slice(x0, x1))
    legend = (slice(y0 + line, py0 - 2), slice(x0, x1))
    assert np.abs(same[readout].astype(int) - off[readout]).sum() > 255 * 20  # +0.0000, +0.5000
    assert np.array_equal(same[legend], off[legend])
    assert (same[readout] > 200).sum() > 50  # white text on the dark box


def test_inset_traces_both_engines_up_to_the_frame_time_only(
        inset_tracks: dict[str, Track]) -> None:
    from tippetop.mujoco_runner.inset import TRACE_RGB

    for t in (0.25, 0.5, 1.0):
        frame, layout = _draw_inset(inset_tracks["mujoco"], inset_tracks["off"], t)
        px0, py0, px1, py1 = layout.plot
        plot = frame[py0:py1, px0:px1]
        now = t * (px1 - px0)  # the frame time's column
        for rgb in TRACE_RGB:
            rows, cols = np.nonzero(np.all(plot == rgb, axis=2))
            assert len(cols) > now  # a trace, at least a pixel a column
            assert cols.min() <= 1 and now - 3 <= cols.max() <= now + 3, (t, rgb, cols.max())
        # theta rises from 0.1 (bottom) to 3.0 (top): the trace's last column is higher
        rows, cols = np.nonzero(np.all(plot == TRACE_RGB[0], axis=2))
        assert rows[cols == cols.min()].mean() > rows[cols == cols.max()].mean() + 5 * t


def test_inset_is_drawn_into_the_frames_of_two_tracks_only(backend: str,
                                                         inset_tracks: dict[str, Track]) -> None:
    from tippetop.mujoco_runner import video
    from tippetop.mujoco_runner.inset import inset_layout

    tracks = [inset_tracks["mujoco"], inset_tracks["off"]]
    times = np.array([0.0, 0.5])

    def frames(tracks: list[Track], inset: bool) -> np.ndarray:
        return np.stack(list(video.render_frames(tracks, times, width=320, height=240,
                                                 backend=backend, inset=inset)))

    plain, with_inset = frames(tracks, False), frames(tracks, True)
    assert plain.shape == with_inset.shape == (2, 240, 640, 3)
    x0, y0, x1, y1 = inset_layout(320, 240).box
    inside = np.zeros(plain.shape[1:3], bool)
    inside[y0:y1, x0:x1] = True
    assert np.array_equal(plain[:, ~inside], with_inset[:, ~inside])
    assert np.abs(plain[:, inside].astype(int) - with_inset[:, inside]).mean() > 30
    # one track: one panel, no inset
    assert np.array_equal(frames(tracks[:1], True), plain[:, :, :320])


def test_the_stem_of_a_turned_over_top_shows(backend: str, inset_tracks: dict[str, Track]) -> None:
    """theta = pi - 0.05: the drawn stem (1.55 R) points into the table; the camera is low and
    the table translucent, so it shows below the ball (and the marker with it)."""
    from tippetop.mujoco_runner import offscreen, poses

    top_model = inset_tracks["mujoco"].top_model
    track = _synthetic_track(top_model, "x", lambda t: np.full_like(t, np.pi - 0.05))
    data = mujoco.MjData(top_model.model)
    poses.set_pose(top_model, data, track.at([0.0])[0].qpos)
    camera = offscreen.tracking_camera(top_model)
    with offscreen.OffscreenRenderer(top_model.model, 320, 240, backend) as renderer:
        shown = renderer.render(data, camera).astype(int)
        renderer._option.geomgroup[1] = 0  # the stem and the marker are visual, group 1
        hidden = renderer.render(data, camera).astype(int)
    rows, cols = np.nonzero(np.abs(shown - hidden).sum(axis=2) > 40)
    assert len(rows) > 60, len(rows)
    assert rows.min() > 120  # all of it below the ball's centre (the middle of the picture)


# ---------------------------------------------------------------- bad input
def _main(argv: list[str], monkeypatch: pytest.MonkeyPatch) -> int:
    """``tippetop`` with the render subcommand (added here until compare.cli registers it)."""
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    if "render" not in sub.choices:
        render_command.add_parser(sub)
    monkeypatch.setattr(cli, "build_parser", lambda: parser)
    return cli.main(argv)


@pytest.mark.parametrize(("args", "env", "says"), [
    (["--size", "10xabc"], None, "--size: expected WIDTHxHEIGHT"),
    (["--fps", "0"], None, "--fps: expected"),
    (["--speed", "-1"], None, "--speed: expected"),
    (["--engine", "blender"], None, "--engine: expected one of mujoco|ode"),
    (["--engines", "mujoco,mujoco"], None, "--engines: expected mujoco, ode or mujoco,ode"),
    (["--engine", "ode", "--engines", "mujoco,ode"], None, "--engines: expected --engine or "
     "--engines"),
    (["--out", "video.avi"], None, "--out: expected a file ending in .mp4"),
    (["--out", "taken.mp4"], None, "--out: expected a path that does not exist yet"),
    (["--speed", "0.004"], None, "--max-frames: expected at most 3000 frames, got 3751"),
    ([], "nonsense", "MUJOCO_GL: expected egl or osmesa"),
])
def test_bad_input_is_one_line_and_leaves_no_file(
    args: list[str], env: str | None, says: str, tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "taken.mp4").write_text("keep me")
    if env is not None:
        monkeypatch.setenv("MUJOCO_GL", env)
    code = _main(["render", "fig3", "--set", "run.t_end_s=0.5", "--speed", "1", *args],
                 monkeypatch)
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("tippetop: error: ") and says in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken.mp4"]
    assert (tmp_path / "taken.mp4").read_text() == "keep me"


def test_no_backend_names_the_debian_packages(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.setattr(gl, "_egl_problem", lambda: "libEGL.so.1: cannot open")
    monkeypatch.setattr(gl, "_osmesa_problem", lambda: "libOSMesa.so.8: cannot open")
    with pytest.raises(TippetopError) as info:
        gl.choose_gl_backend()
    msg = str(info.value)
    assert "\n" not in msg
    assert "libegl1 libopengl0 libgl1-mesa-dri" in msg and "libosmesa6" in msg
    # EGL missing, OSMesa there: OSMesa is used
    monkeypatch.setattr(gl, "_osmesa_problem", lambda: None)
    assert gl.choose_gl_backend() == "osmesa"


def test_cli_writes_the_default_name_and_refuses_to_overwrite(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
    backend: str,
) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MUJOCO_GL", backend)
    argv = ["render", "fig3", "--engine", "ode", "--set", "run.t_end_s=0.2", "--speed", "1",
            "--fps", "20", "--size", "96x64"]
    assert _main(argv, monkeypatch) == 0
    out, err = capsys.readouterr()
    assert "wrote fig3.mp4: 5 frames 96x64" in out
    # what it is doing, one line a step, while it does it
    assert err.splitlines() == [
        "simulating fig3 in the reference ODE (0.2 s simulated)...",
        "replaying the reference's in the MJCF: 5 frames of 96x64, 0.25 s of video at "
        f"speed 1 ({backend})..."], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fig3.mp4"]
    assert _frames(tmp_path / "fig3.mp4").shape == (5, 64, 96, 3)
    assert _main(argv, monkeypatch) == 2
    assert _main([*argv, "--force"], monkeypatch) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fig3.mp4"]


def test_the_summary_line_has_four_digits_and_units() -> None:
    """It said "0.967 s of video ... egl, 27 ms a frame" (three digits, then two)."""
    res = render.RenderResult(path=Path("fig3.mp4"), engines=("mujoco",), backend="egl",
                              n_frames=29, width=160, height=120, fps=30.0, speed=8.3,
                              video_s=29 / 30, render_wall_s=0.7737)
    assert render_command.summary_line(res, 8.0) == (
        "wrote fig3.mp4: 29 frames 160x120, 0.9667 s of video at 30 fps for 8 s simulated "
        "(--speed 8.3); egl, 26.68 ms a frame")
    slow = render.RenderResult(path=Path("a.mp4"), engines=("mujoco", "ode"), backend="osmesa",
                               n_frames=1281, width=1280, height=480, fps=30.0, speed=0.25,
                               video_s=1281 / 30, render_wall_s=1601.25)
    assert render_command.summary_line(slow, 10.675) == (
        "wrote a.mp4: 1,281 frames 1280x480, 42.7 s of video at 30 fps for 10.68 s simulated "
        "(--speed 0.25); osmesa, 1.25 s a frame")


# ---------------------------------------------------------------- OpenGL only when asked
_GL_MODULES = ("OpenGL", "mujoco.egl", "mujoco.osmesa", "mujoco.glfw", "glfw",
               "tippetop.mujoco_runner.video", "tippetop.mujoco_runner.offscreen",
               "tippetop.mujoco_runner.overlay", "tippetop.mujoco_runner.inset",
               "tippetop.mujoco_runner.mp4", "imageio", "imageio_ffmpeg", "PIL")


def test_simulation_and_cli_never_set_up_opengl(tmp_path: Path) -> None:
    """In a fresh process: importing the simulation, building the command line, a simulate run
    and a rejected render import no GL backend or video code, and leave MUJOCO_GL at "disable".

    (With MUJOCO_GL unset, ``import mujoco`` imports its windowed backend, the glfw bindings,
    which start a Python subprocess per GLFW library they find; stopped midway, such a
    subprocess printed a traceback into the user's terminal. tippetop sets MUJOCO_GL=disable
    before MuJoCo is imported when the user has not set it: no OpenGL at all, and no
    subprocess. The offscreen backends are ours to pick, and only render picks one.)
    """
    code = textwrap.dedent(f"""
        import argparse, os, sys
        import tippetop.compare.cli, tippetop.reference_ode.solve, tippetop.mujoco_runner.run
        import tippetop.compare.commands.render, tippetop.compare.presentation.video
        from tippetop.compare import cli
        parser = cli.build_parser()
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        if "render" not in sub.choices:
            tippetop.compare.commands.render.add_parser(sub)
        cli.build_parser = lambda: parser
        assert cli.main(["simulate", "fig3", "--engine", "mujoco", "--set",
                         "run.t_end_s=0.01", "--json"]) == 0
        assert cli.main(["render", "fig3", "--fps", "0"]) == 2
        loaded = [m for m in sys.modules if m.startswith({_GL_MODULES!r})]
        print("LOADED", loaded, os.environ.get("MUJOCO_GL"), os.environ.get("PYOPENGL_PLATFORM"))
    """)
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "LOADED [] disable None" in out.stdout, out.stdout
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------- a full disk (issue 23)
_FULL_ARGV = ["render", "fig3", "--engine", "ode", "--set", "run.t_end_s=0.5", "--speed", "1",
              "--fps", "20", "--size", "320x240"]


def _full_disk_line(code: int, err: str, path: Path) -> str:
    """The one error line of a render that ran out of room: ENOSPC and the file, exit 1."""
    lines = [x for x in err.splitlines() if x.startswith("tippetop:")]
    assert code == 1 and len(lines) == 1, err
    line = lines[0]
    assert line.startswith(f"tippetop: video failed: could not write {path}: No space left on "
                           "device (ENOSPC: "), line
    assert "does not decode" not in line and line.endswith(f"{path} not written"), line
    return line


def test_a_full_disk_under_the_decoder_check_is_said_to_be_the_disk(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        backend: str) -> None:
    """The issue: on a full disk ffmpeg ended without an error and left a cut file, and the
    user read "the file does not decode (Could not load meta information)". The free space,
    read while the cut file is still there, says what to fix."""
    from tippetop.mujoco_runner import video

    def cut(path: Path, *args: object) -> None:
        raise video.VideoCheckFailed("the file does not decode (Could not load meta "
                                     "information)")

    monkeypatch.setenv("MUJOCO_GL", backend)
    monkeypatch.setattr(video, "verify_video", cut)
    monkeypatch.setattr(pvideo, "free_bytes", lambda folder: 0)
    out = tmp_path / "v.mp4"
    code = _main([*_FULL_ARGV, "--out", str(out)], monkeypatch)
    line = _full_disk_line(code, capsys.readouterr().err, out)
    assert f"0 bytes free on the filesystem of {tmp_path}" in line
    assert list(tmp_path.iterdir()) == []  # no partial file, no temporary


def test_a_writer_that_hits_enospc_names_the_errno(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        backend: str) -> None:
    import errno

    from tippetop.mujoco_runner import mp4

    def write(self: mp4.Mp4Writer, rgb: np.ndarray) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setenv("MUJOCO_GL", backend)
    monkeypatch.setattr(mp4.Mp4Writer, "write", write)
    out = tmp_path / "v.mp4"
    code = _main([*_FULL_ARGV, "--out", str(out)], monkeypatch)
    _full_disk_line(code, capsys.readouterr().err, out)
    assert list(tmp_path.iterdir()) == []


def test_a_cut_file_on_a_disk_with_room_is_not_called_a_full_disk(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import errno

    from tippetop.mujoco_runner import video

    cut = video.VideoCheckFailed("the file does not decode (moov atom not found)")
    monkeypatch.setattr(pvideo, "free_bytes", lambda folder: 10 << 30)
    assert pvideo.disk_full(cut, tmp_path) is None
    monkeypatch.setattr(pvideo, "free_bytes", lambda folder: 0)
    assert pvideo.disk_full(cut, tmp_path).errno == errno.ENOSPC
    said = pvideo.disk_full(RuntimeError("ffmpeg: No space left on device"), tmp_path)
    assert said is not None and said.errno == errno.ENOSPC


@pytest.fixture
def tiny_disk(tmp_path: Path) -> Iterator[Path]:
    """A 64 kB tmpfs, nearly filled: a real full disk (root only; skipped where it cannot be
    mounted)."""
    folder = tmp_path / "tiny"
    folder.mkdir()
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(folder)],
                             capture_output=True, text=True, check=False)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.strip()}")
    try:
        (folder / "filler").write_bytes(b"\0" * (64 * 1024 - 8 * 1024))
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=False)


def test_render_on_a_real_full_disk_says_the_disk_is_full(
        tiny_disk: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        backend: str) -> None:
    monkeypatch.setenv("MUJOCO_GL", backend)
    out = tiny_disk / "v.mp4"
    code = _main([*_FULL_ARGV, "--out", str(out)], monkeypatch)
    _full_disk_line(code, capsys.readouterr().err, out)
    assert sorted(p.name for p in tiny_disk.iterdir()) == ["filler"]
