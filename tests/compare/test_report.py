"""The model-validation report: self-contained, complete, and rendered by a real browser.

A tiny nightly (reference ODE only: the Fig. 3 top under three friction laws, a short Fig. 7 (b)
run, a 20-s n1 bisection and a 3-point Fig. 9 (a) sweep) provides the results. The browser test
opens the report in headless Debian chromium through the DevTools protocol on a pipe
(``--remote-debugging-pipe``: no port, no extra package), and checks that the page loads with
no console error, log error or exception (the report's Content-Security-Policy turns any
external load into such an error), that every ``<img>`` decoded (``naturalWidth > 0``), and
that a screenshot is not blank. It is skipped only when chromium is not installed.
"""

from __future__ import annotations

import base64
import contextlib
import fcntl
import io
import json
import os
import select
import shutil
import subprocess
import sys
import time
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tippetop.compare.commands import nightly as nightly_command
from tippetop.compare.report import build_report, friction_note
from tippetop.models.numbers import number_text

TINY = """
[profiles.tiny]
description = "report test"

[[case]]
name = "fig3"
category = "paper"
kind = "run"
scene = "fig3"
engines = ["ode"]
modes = ["paper", "viscous", "coulomb"]
profiles = ["tiny"]
metrics = ["outcome", "theta_asymp", "t_invert", "J_rel_drift", "energy_lost"]

[[case]]
name = "fig7b-short"
category = "groups"
kind = "run"
scene = "fig7b"
set = ["run.t_end_s=2"]
engines = ["ode"]
modes = ["paper"]
profiles = ["tiny"]
metrics = ["outcome"]

[[case]]
name = "n1-20s"
category = "thresholds"
kind = "threshold"
scene = "fig11_n060"
set = ["run.t_end_s=20"]
which = "n1"
rel_tol = 0.1
points_per_round = 2
engines = ["ode"]
modes = ["paper"]
profiles = ["tiny"]
metrics = ["measured"]

[[case]]
name = "fig9a-tiny"
category = "sweeps"
kind = "sweep"
scene = "fig11_n060"
set = ["run.t_end_s=20"]
n0 = "30:60:15"
figure = "Fig. 9"
label = "(a)"
engines = ["ode"]
modes = ["paper"]
profiles = ["tiny"]
metrics = ["theta_asymp_vs_n0"]
"""
#: Figures of the tiny report: fig3's main modes (the reference only), its other modes (folded),
#: fig7b, 1 sweep figure, 1 group map.
N_FIGURES = 5
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


@pytest.fixture(scope="module")
def nightly_out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("report")
    (root / "tiny.toml").write_text(TINY)
    out, err = io.StringIO(), io.StringIO()
    with pytest.MonkeyPatch.context() as mp, contextlib.redirect_stdout(out), \
            contextlib.redirect_stderr(err):
        mp.setenv("TIPPETOP_CACHE", str(root / "cache"))
        code = nightly_command.main(["--catalogue", str(root / "tiny.toml"), "--profile", "tiny",
                             "--baseline", str(root / "baselines"), "--update-baseline",
                             "--out", str(root / "out"), "--workers", "1"])
    assert code == 0, out.getvalue() + err.getvalue()
    return root / "out"


class _Page(HTMLParser):
    """Collects tags, attributes and ids of an HTML page."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str | None]]] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append((tag, dict(attrs)))


def _parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    return page


def test_report_is_self_contained(nightly_out: Path) -> None:
    page = _parse(nightly_out / "report.html")
    tags = [t for t, _ in page.tags]
    assert "script" not in tags and "link" not in tags and "iframe" not in tags
    imgs = [a for t, a in page.tags if t == "img"]
    assert len(imgs) == N_FIGURES
    for a in imgs:
        src = a["src"] or ""
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
    for _, attrs in page.tags:
        for key in ("src", "href"):
            v = attrs.get(key)
            assert v is None or v.startswith(("data:", "#")), v
    csp = [a for t, a in page.tags if t == "meta" and a.get("http-equiv") ==
           "Content-Security-Policy"]
    assert csp and "default-src 'none'" in csp[0]["content"]


def test_report_has_every_section(nightly_out: Path) -> None:
    text = (nightly_out / "report.html").read_text()
    ids = {a.get("id") for _, a in _parse(nightly_out / "report.html").tags}
    assert {"verdict", "checks", "scenes", "timeseries", "sweeps", "groups", "friction",
            "thresholds", "accuracy", "all", "env"} <= ids
    for needle in ("xi_plus", "slip speed of the contact point", "1 - a/R", "1 + a/R",
                   "theta_s(n0)", "No accuracy-versus-cost figures"):
        assert needle in text, needle
    # the friction-law table: a row per mode, with its sentence written from the numbers
    res = json.loads((nightly_out / "results.json").read_text())
    rows = {r["mode"]: r for r in res["cases"] if r["name"] == "fig3"}
    ref = rows["paper"]
    coulomb = friction_note(rows["coulomb"], ref)
    assert "does not invert within 8 s" in coulomb and "sticks into rolling" in coulomb
    viscous = friction_note(rows["viscous"], ref)
    assert f"inverts at {number_text(rows['viscous']['values']['t_invert'], 's')}" in viscous
    for note in (coulomb, viscous):
        assert note in text.replace("&#x27;", "'")
    # the threshold table: theory and measured side by side
    th = next(r for r in res["cases"] if r["kind"] == "threshold")["threshold"]
    assert f"{th['theory']:.4g}" in text and f"{th['measured']:.4g}" in text


def test_report_rebuilds_from_results_json_alone(nightly_out: Path, tmp_path: Path) -> None:
    """``build_report`` reads results.json and the tables/ files beside it, and embeds the
    accuracy figures of a folder."""
    acc = tmp_path / "acc"
    acc.mkdir()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(2, 2))
    ax.loglog([1, 10], [1e-3, 1e-9])
    fig.savefig(acc / "accuracy_ode_fig3.png")
    plt.close(fig)
    out = build_report(nightly_out / "results.json", tmp_path / "again.html", accuracy_dir=acc)
    page = _parse(out)
    assert len([1 for t, _ in page.tags if t == "img"]) == N_FIGURES + 1
    assert "accuracy_ode_fig3.png" in out.read_text()


def _find_chromium() -> str | None:
    for name in CHROMIUM_NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


class _DevTools:
    """The Chrome DevTools protocol over ``--remote-debugging-pipe`` (fds 3 and 4)."""

    def __init__(self, exe: str, profile_dir: Path, timeout_s: float = 60.0) -> None:
        to_chrome_r, self._w = os.pipe()
        self._r, from_chrome_w = os.pipe()

        def wire_fds() -> None:  # in the child: its fd 3 reads commands, fd 4 writes replies
            a = fcntl.fcntl(to_chrome_r, fcntl.F_DUPFD_CLOEXEC, 10)
            b = fcntl.fcntl(from_chrome_w, fcntl.F_DUPFD_CLOEXEC, 10)
            os.dup2(a, 3)
            os.dup2(b, 4)

        self.proc = subprocess.Popen(
            [exe, "--headless", "--no-sandbox", "--disable-gpu",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--no-first-run", "--disable-extensions", f"--user-data-dir={profile_dir}",
             "--remote-debugging-pipe", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            close_fds=False, preexec_fn=wire_fds)
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self.timeout_s = timeout_s
        self._buf = b""
        self._id = 0
        self.events: list[dict[str, Any]] = []

    def _message(self) -> dict[str, Any]:
        deadline = time.monotonic() + self.timeout_s
        while b"\0" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self._r], [], [], left)[0]:
                raise TimeoutError("no answer from chromium")
            chunk = os.read(self._r, 1 << 20)
            if not chunk:
                raise RuntimeError("chromium closed the DevTools pipe")
            self._buf += chunk
        msg, self._buf = self._buf.split(b"\0", 1)
        return json.loads(msg)

    def call(self, method: str, session: str | None = None, **params: Any) -> dict[str, Any]:
        self._id += 1
        cmd: dict[str, Any] = {"id": self._id, "method": method, "params": params}
        if session:
            cmd["sessionId"] = session
        os.write(self._w, json.dumps(cmd).encode() + b"\0")
        while True:
            msg = self._message()
            if msg.get("id") == self._id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg["result"]
            self.events.append(msg)

    def wait_for(self, method: str) -> dict[str, Any]:
        for i, ev in enumerate(self.events):
            if ev.get("method") == method:
                return self.events.pop(i)
        while True:
            msg = self._message()
            if msg.get("method") == method:
                return msg
            self.events.append(msg)

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.call("Browser.close")
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._w)
        os.close(self._r)


def _browser(tmp_path: Path) -> _DevTools:
    """Headless chromium on a DevTools pipe (the test is skipped without chromium)."""
    exe = _find_chromium()
    if exe is None:
        pytest.skip("chromium is not installed (apt-get install -y chromium); CI installs it")
    return _DevTools(exe, tmp_path / "chromium-profile")


def _open(browser: _DevTools, page: Path, width: int, height: int,
          domains: tuple[str, ...]) -> str:
    """A new tab of ``width`` x ``height`` CSS pixels showing ``page``; its session id."""
    target = browser.call("Target.createTarget", url="about:blank")["targetId"]
    session = browser.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
    for domain in domains:
        browser.call(f"{domain}.enable", session)
    browser.call("Emulation.setDeviceMetricsOverride", session, width=width, height=height,
                 deviceScaleFactor=1, mobile=False)
    browser.call("Page.navigate", session, url=page.resolve().as_uri())
    browser.wait_for("Page.loadEventFired")
    return session


def test_report_renders_in_headless_chromium(nightly_out: Path, tmp_path: Path) -> None:
    browser = _browser(tmp_path)
    try:
        session = _open(browser, nightly_out / "report.html", 1300, 1000,
                        ("Page", "Runtime", "Log"))
        images = browser.call(
            "Runtime.evaluate", session, returnByValue=True,
            expression="Array.from(document.images).map(i => [i.complete, i.naturalWidth, "
                       "i.naturalHeight])")["result"]["value"]
        title = browser.call("Runtime.evaluate", session, expression="document.title",
                             returnByValue=True)["result"]["value"]
        shot = browser.call("Page.captureScreenshot", session, format="png",
                            captureBeyondViewport=True,
                            clip={"x": 0, "y": 0, "width": 1300, "height": 2400, "scale": 1})
        problems = [ev for ev in browser.events
                    if ev.get("method") == "Runtime.exceptionThrown"
                    or (ev.get("method") == "Runtime.consoleAPICalled"
                        and ev["params"]["type"] in ("error", "assert"))
                    or (ev.get("method") == "Log.entryAdded"
                        and ev["params"]["entry"]["level"] == "error")]
    finally:
        browser.close()
    assert problems == []
    assert title.startswith("tippetop report")
    assert len(images) == N_FIGURES
    assert all(complete and w > 0 and h > 0 for complete, w, h in images), images
    import matplotlib.image as mpimg

    pixels = mpimg.imread(io.BytesIO(base64.b64decode(shot["data"])), format="png")
    assert pixels.shape[0] == 2400 and pixels.shape[1] == 1300
    rgb = np.asarray(pixels)[..., :3]
    assert float(rgb.std()) > 0.05  # not a blank page
    assert float((rgb.mean(axis=2) < 0.5).mean()) > 0.01  # text and figures drawn in dark ink


def test_the_verdict_is_on_the_first_screen(nightly_out: Path, tmp_path: Path) -> None:
    """At 1280x900, the verdict table (every scene in every mode against the theory) lies
    wholly inside the first screen, above every figure, and the page does not scroll
    sideways."""
    browser = _browser(tmp_path)
    try:
        session = _open(browser, nightly_out / "report.html", 1280, 900, ("Page",))
        geo = browser.call("Runtime.evaluate", session, returnByValue=True, expression="""(() => {
            const t = document.querySelector('section#verdict table');
            const r = t.getBoundingClientRect();
            const imgs = Array.from(document.images).map(i => i.getBoundingClientRect().top);
            return {top: r.top, bottom: r.bottom, right: r.right, rows: t.rows.length,
                    firstImg: Math.min(...imgs), scrollW: document.documentElement.scrollWidth,
                    cells: Array.from(t.querySelectorAll('tbody td'))
                                .map(d => d.className).filter(c => c && c !== 'na')};
        })()""")["result"]["value"]
        shot = browser.call("Page.captureScreenshot", session, format="png")
    finally:
        browser.close()
    (tmp_path / "first-screen.png").write_bytes(base64.b64decode(shot["data"]))
    assert 0 <= geo["top"] < geo["bottom"] <= 900, geo
    assert geo["right"] <= 1280 and geo["scrollW"] <= 1280, geo
    assert geo["bottom"] <= geo["firstImg"], geo
    res = json.loads((nightly_out / "results.json").read_text())
    scenes = {r["scene"] for r in res["crossval"]}
    assert geo["rows"] == 1 + len(scenes)  # the header row and a row per scene
    assert len(geo["cells"]) == len(res["crossval"])
    assert set(geo["cells"]) <= {"agree", "depart", "inconclusive", "failed"}


def test_results_crossval_rows(nightly_out: Path) -> None:
    """results.json's crossval: a row per run case with the contract's keys; the reference's
    Fig. 3 run agrees with the theory (inverted, theta_asymp within 0.05 rad of pi) and exact
    Coulomb departs from it (the top sticks into rolling and stays upright)."""
    res = json.loads((nightly_out / "results.json").read_text())
    keys = {"scene", "mode", "outcome", "theory_outcome", "theta_asymp", "theta_s",
            "d_theta_asymp", "t_invert", "d_t_invert", "J_rel_drift", "agrees"}
    runs = [r for r in res["cases"] if r["kind"] == "run"]
    assert len(res["crossval"]) == len(runs)
    rows = {(r["scene"], r["mode"]): r for r in res["crossval"]}
    for r in rows.values():
        assert keys <= set(r)
    ode = rows[("fig3", "paper")]
    assert ode["agrees"] and ode["theory_outcome"] == "inverted"
    assert abs(ode["theta_s"] - np.pi) < 1e-9 and abs(ode["d_theta_asymp"]) <= 0.05
    coulomb = rows[("fig3", "coulomb")]
    assert not coulomb["agrees"] and coulomb["outcome"] == "upright"
    assert coulomb["d_t_invert"] is None
    viscous = rows[("fig3", "viscous")]
    assert viscous["d_t_invert"] == pytest.approx(viscous["t_invert"] - ode["t_invert"])


def test_the_readmes_rebuild_command_works_on_a_fresh_nightly_folder(
        nightly_out: Path, tmp_path: Path) -> None:
    """``tippetop report DIR/results.json``, as the docs give it, replaces the report the
    nightly wrote; a report.html tippetop did not write is kept without --force, in one line
    that does not name an --out the user never passed."""
    folder = tmp_path / "night"
    shutil.copytree(nightly_out, folder)
    cmd = [sys.executable, "-m", "tippetop.compare", "report", str(folder / "results.json")]
    before = (folder / "report.html").stat().st_mtime_ns
    res = subprocess.run(cmd, capture_output=True, text=True, check=False)
    assert res.returncode == 0 and res.stdout.strip() == str(folder / "report.html"), res.stderr
    assert (folder / "report.html").stat().st_mtime_ns != before
    (folder / "report.html").write_text("<p>my notes</p>")
    res = subprocess.run(cmd, capture_output=True, text=True, check=False)
    assert res.returncode == 2 and "--out" not in res.stderr.split(":", 2)[1]
    assert res.stderr.count("\n") == 1 and "tippetop did not write it" in res.stderr
    assert (folder / "report.html").read_text() == "<p>my notes</p>"
    res = subprocess.run([*cmd, "--force"], capture_output=True, text=True, check=False)
    assert res.returncode == 0 and "<!DOCTYPE html>" in (folder / "report.html").read_text()


def test_the_old_rebuild_spelling_still_runs_with_one_note(nightly_out: Path,
                                                            tmp_path: Path) -> None:
    """``python -m tippetop.compare.report`` is kept for one release: one line says the new
    spelling, then it rebuilds as ``tippetop report`` does."""
    folder = tmp_path / "night"
    shutil.copytree(nightly_out, folder)
    res = subprocess.run([sys.executable, "-m", "tippetop.compare.report",
                          str(folder / "results.json")], capture_output=True, text=True,
                         check=False)
    assert res.returncode == 0 and res.stdout.strip() == str(folder / "report.html")
    assert res.stderr.splitlines() == [
        "tippetop: note: 'python -m tippetop.compare.report' is now 'tippetop report'; this "
        "spelling goes in the next release"]
