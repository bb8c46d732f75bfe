"""``nightly --videos``: every scene's video fits its frame cap, and every failure, whatever it
is, is listed with a one-line reason and leaves no file behind.

The arithmetic is checked for every scene of the catalogue without rendering; the failure
handling with a stand-in renderer; one real render of a 0.3-s Fig. 3 checks the wiring.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import imageio.v3 as iio
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tippetop.compare.nightly import videos
from tippetop.compare.nightly.catalogue import Case, load_catalogue
from tippetop.compare.presentation import video
from tippetop.compare.studies import render
from tippetop.models.errors import TippetopError
from tippetop.models.scene import Scene, catalogue_names, load_scene
from tippetop.mujoco_runner import gl


def _paper_scenes() -> list[str]:
    """Every catalogue scene, and every scene of the nightly catalogue's paper run cases."""
    nightly = videos.video_scenes(load_catalogue().cases)
    assert "fig3" in nightly
    return sorted(set(catalogue_names()) | set(nightly))


@pytest.mark.parametrize("name", _paper_scenes())
def test_every_scene_video_fits_the_frame_cap(name: str) -> None:
    """The nightly wrote 0 of 13 videos: each got VIDEO_MAX_FRAMES + 1 frames (241 > 240)."""
    t_end = load_scene(name, list(videos.VIDEO_OVERRIDES)).run.t_end_s
    speed = videos.video_speed(t_end)
    n = video.frame_count(t_end, videos.VIDEO_FPS, speed)
    assert n <= videos.VIDEO_MAX_FRAMES
    # what render_scene checks before simulating anything, with the nightly's numbers
    assert video.check_timing(t_end, videos.VIDEO_FPS, speed, videos.VIDEO_MAX_FRAMES) == n
    assert speed >= videos.VIDEO_MIN_SPEED
    last = (n - 1) * speed / videos.VIDEO_FPS
    assert last <= t_end * (1 + 1e-9)
    if speed > videos.VIDEO_MIN_SPEED:  # the cap decides: all of it, the end included
        assert n == videos.VIDEO_MAX_FRAMES
        assert last == pytest.approx(t_end, rel=1e-9)


@settings(max_examples=300, deadline=None)
@given(t_end=st.floats(1e-3, 1e4), fps=st.floats(1.0, 240.0),
       max_frames=st.integers(2, 10_000), min_speed=st.sampled_from([0.0, 0.25, 1.0]))
def test_speed_to_fit_never_exceeds_the_cap_and_shows_the_end(
        t_end: float, fps: float, max_frames: int, min_speed: float) -> None:
    speed = video.speed_to_fit(t_end, fps, max_frames, min_speed=min_speed)
    n = video.frame_count(t_end, fps, speed)
    assert 1 <= n <= max_frames
    if speed > min_speed:
        # all the frames allowed, the last one on t_end
        assert n == max_frames
        assert (n - 1) * speed / fps == pytest.approx(t_end, rel=1e-9)
    else:
        assert speed == min_speed


def test_speed_to_fit_refuses_one_frame() -> None:
    with pytest.raises(ValueError, match="max_frames"):
        video.speed_to_fit(8.0, 15.0, 1)


# ---------------------------------------------------------------- failures
def _cases(*scenes: str) -> list[Case]:
    base = Case(id="", name="", category="paper", kind="run", scene="", engine="ode", mode="paper",
                metrics=(), profiles=("quick",))
    cases = [replace(base, id=f"paper/{s}[ode/paper]", name=s, scene=s) for s in scenes]
    # neither a threshold case nor another category gets a video
    cases.append(replace(base, id="thresholds/x[ode/paper]", kind="threshold", scene="fig6"))
    cases.append(replace(base, id="groups/x[ode/paper]", category="groups", scene="fig7a"))
    return cases


def test_every_failure_is_listed_on_one_line_and_leaves_no_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls: dict[str, tuple[float, dict[str, Any]]] = {}

    def fake_render_scene(scene: Scene, out: Path, **kw: Any) -> render.RenderResult:
        calls[scene.name] = (scene.run.t_end_s, kw)
        out = Path(out)
        n = video.frame_count(scene.run.t_end_s, kw["video"].fps, kw["video"].speed)
        if scene.name == "fig3":  # a crash half-way through writing
            out.write_bytes(b"partial")
            (out.parent / f".{out.name}.x1y2.tmp").write_bytes(b"partial")
            raise RuntimeError("ffmpeg died\n  with a second line")
        if scene.name == "fig4":
            raise TippetopError("--size: expected WIDTHxHEIGHT, got 'x'")
        if scene.name == "fig8a":  # returns, but the file is short of frames
            out.write_bytes(b"short")
            n -= 1
        if scene.name == "fig8b":  # a KeyError from deep inside: no message of its own
            raise KeyError("qpos")
        if scene.name == "fig6":
            out.write_bytes(b"a video")
        return render.RenderResult(path=out, engines=("mujoco", "ode"), backend="egl",
                                   n_frames=n,
                                   width=640, height=240, fps=kw["video"].fps,
                                   speed=kw["video"].speed,
                                   video_s=1.0, render_wall_s=0.5)

    monkeypatch.setattr(render, "render_scene", fake_render_scene)
    lines: list[str] = []
    out = videos.render_videos(_cases("fig3", "fig4", "fig6", "fig8a", "fig8b", "no_such"),
                               tmp_path, lines.append)

    assert set(out) == {"requested", "status", "files", "failed"}
    assert out["requested"] is True
    assert out["files"] == {"fig6": "videos/fig6.mp4"}
    assert sorted(out["failed"]) == ["fig3", "fig4", "fig8a", "fig8b", "no_such"]
    for reason in out["failed"].values():
        assert reason and "\n" not in reason
    assert out["failed"]["fig3"] == "RuntimeError: ffmpeg died with a second line"
    assert out["failed"]["fig4"] == "--size: expected WIDTHxHEIGHT, got 'x'"
    assert out["failed"]["fig8b"] == "KeyError: 'qpos'"
    assert "expected" in out["failed"]["fig8a"] and "frames" in out["failed"]["fig8a"]
    assert out["failed"]["no_such"].startswith("scene: expected")
    assert out["status"] == "1 written, 5 failed"
    # nothing broken or half-written is left; the good one is
    assert sorted(p.name for p in (tmp_path / "videos").iterdir()) == ["fig6.mp4"]
    # each failure said in the log, with its reason
    for name, reason in out["failed"].items():
        assert any(f"videos/{name}.mp4: FAILED: {reason}" in line for line in lines), lines
    # the arguments: side by side, within the cap, said as it goes
    assert sorted(calls) == ["fig3", "fig4", "fig6", "fig8a", "fig8b"]
    for t_end, kw in calls.values():
        shot = kw["video"]
        assert kw["engines"] == ("mujoco", "ode") and shot.max_frames == videos.VIDEO_MAX_FRAMES
        assert shot.speed == videos.video_speed(t_end)
        assert video.frame_count(t_end, shot.fps, shot.speed) <= videos.VIDEO_MAX_FRAMES
        assert callable(kw["say"]) and kw["run"].progress is False


def test_real_short_videos_are_written(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The wiring, with real rendering: 0.3 s of Fig. 3 at quarter speed is 19 frames."""
    monkeypatch.setenv("MUJOCO_GL", gl.choose_gl_backend())  # restored afterwards
    monkeypatch.setattr(videos, "VIDEO_OVERRIDES", ("mujoco.timestep_s=1e-4", "run.t_end_s=0.3"))
    monkeypatch.setattr(videos, "VIDEO_SIZE", (160, 120))
    lines: list[str] = []
    out = videos.render_videos(_cases("fig3"), tmp_path, lines.append)
    assert out == {"requested": True, "status": "1 written",
                   "files": {"fig3": "videos/fig3.mp4"}, "failed": {}}
    frames = iio.imread(tmp_path / "videos" / "fig3.mp4", index=None, plugin="FFMPEG")
    assert frames.shape == (19, 120, 320, 3)
    assert sorted(p.name for p in (tmp_path / "videos").iterdir()) == ["fig3.mp4"]
    said = "\n".join(lines)
    assert "simulating fig3 in MuJoCo (0.3 s simulated)..." in said
    assert "simulating fig3 in the reference ODE (0.3 s simulated)..." in said
    assert "replaying MuJoCo's run and the reference's" in said
