"""MkDocs hook: the site's pictures of a report and a video, made at build time by real commands.

The pages show what ``tippetop validate``'s and ``tippetop nightly``'s ``report.html`` look
like, and frames of ``tippetop render``'s video. No screenshot is committed: every build runs
the commands below into a temporary folder, opens each report in headless Chromium, takes a
few frames of the video (imageio), and adds the PNGs to the site as generated files
(``images/*.png``), so a picture is always of the code that built the site.

The commands run with a cache of their own, ``build/docs-cache/`` (ignored by git): their
runs, the history their ``nightly`` appends to, their compiled code and any managed environment
go there, never into the user's ``$TIPPETOP_CACHE``, so a docs build leaves no run in the user's
``tippetop history`` (:data:`CACHE`, :func:`command_env`). A ``NUMBA_CACHE_DIR`` the user set is
kept. The folder stays between builds, so a second build loads the compiled code. Chromium too
gets a profile, a config and a cache folder of its own, in the temporary folder.

About 50 s on 2 cores (measured with a fresh and with a warm compile cache).
``TIPPETOP_DOCS_IMAGES=0`` skips the commands for a quick local build: the pages then show
placeholders, with one notice (not a warning). A missing Chromium, a missing offscreen OpenGL
or a failing command is one warning line naming it, which fails ``properdocs build --strict``.
"""

from __future__ import annotations

import io
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from mkdocs.config.defaults import MkDocsConfig
from mkdocs.structure.files import File, Files

log = logging.getLogger("mkdocs.hooks.tippetop_images")

#: Set to 0 to skip the commands (placeholders instead).
ENV = "TIPPETOP_DOCS_IMAGES"

#: Chromium's window (px) and the height each screenshot is cropped to (the report's top).
WINDOW = (1300, 1800)
CROP_VALIDATE = 1100
CROP_NIGHTLY = 1560

#: The MJCF top whose validation report is shown (relative to the repository).
VALIDATE_MODEL = "examples/paper_loaded_sphere.xml"
#: The nightly cases whose report is shown: the paper's Fig. 3 scene in every mode of the quick
#: profile (a glob over the catalogue's case ids, models/nightly.toml).
NIGHTLY_CASES = "paper/fig3*"
#: Frames of the side-by-side video put in the strip (3 columns, 2 rows).
STRIP_FRAMES = 6

#: The fidelity map's measured results (the default grid takes about 30 min on 2 cores, too
#: long for a build): the figure is drawn from them by today's code.
FIDELITY_RESULTS = "docs/data/fidelity-default.json"
#: Today's work-precision sweep (``tippetop bench ode --sweep``, about 3 min on 2 cores):
#: its figures are drawn from the results at build time.
WORK_PRECISION_RESULTS = "docs/data/work-precision.json"

#: Each command's time limit (s): a hung command is a failed image, not a hung build.
TIMEOUT_S = 600

#: The repository (this file is docs/hooks/images.py).
ROOT = Path(__file__).resolve().parents[2]
#: The commands' own ``TIPPETOP_CACHE`` (relative to the repository; ``build/`` is ignored by
#: git): their run cache, history, compiled code and managed environments, kept between builds.
CACHE = Path("build") / "docs-cache"

#: The generated images: site path -> (what it shows, for the placeholder).
IMAGES = {
    "images/validate-report.png": f"tippetop validate {VALIDATE_MODEL} --no-tune: report.html",
    "images/nightly-report.png": (f"tippetop nightly --profile quick --cases '{NIGHTLY_CASES}':"
                                  " report.html"),
    "images/render-strip.png": "tippetop render fig3 --engines mujoco,ode: frames of the MP4",
    "images/contact-lift.png": ("python -m tippetop.compare.report.lift: the slip above "
                                "which MuJoCo's contact lifts the ball"),
    "images/contact-window.png": ("python -m tippetop.compare.report.window: each step's "
                                  "contact against the samples"),
    "images/fidelity-map.png": ("python -m tippetop.compare.report.fidelity "
                                f"{FIDELITY_RESULTS}: the default grid's map"),
    **{f"images/work-precision-{top}.png": (
        "python -m tippetop.compare.studies.work_precision_report "
        f"{WORK_PRECISION_RESULTS} {top}: today's frontier") for top in ("fig3", "fig11", "stiff")},
}


#: The probes' figures (``tippetop probe --out``: each probe's motion against its exact curve)
#: and today's table of every probe over the installed MuJoCo's integrators, which
#: docs/physics/probes.md shows where it writes ``{{ probe_table }}``.
PROBE_INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")
PROBE_TABLE_MARKER = "{{ probe_table }}"


def _probe_names() -> tuple[str, ...]:
    from tippetop.compare.probes import probe_names

    return probe_names()


IMAGES.update({f"images/probe-{name}.png": f"tippetop probe {name} --out DIR: {name}.png"
               for name in _probe_names()})
#: The table made by this build (markdown), or why there is none.
_PROBE_TABLE = {"text": ""}


class ImageError(Exception):
    """An image that could not be made: one line saying why."""


def on_files(files: Files, config: MkDocsConfig) -> Files:
    """Add the images to the site as generated files (made here, or placeholders)."""
    for name, data in _images(config).items():
        files.append(File.generated(config, name, content=data))
    return files


def _images(config: MkDocsConfig) -> dict[str, bytes]:
    if os.environ.get(ENV, "").strip() == "0":
        log.info("%s=0: the report screenshots and the video strip are placeholders", ENV)
        return {name: _placeholder(f"not built ({ENV}=0): {what}")
                for name, what in IMAGES.items()}
    root = Path(config.config_file_path).resolve().parent
    start = time.perf_counter()
    out: dict[str, bytes] = {}
    makers: dict[str, Callable[[Path, Path], bytes]] = {
        "images/validate-report.png": _validate_report,
        "images/nightly-report.png": _nightly_report,
        "images/render-strip.png": _render_strip,
        "images/contact-lift.png": _contact_lift,
        "images/contact-window.png": _contact_window,
        "images/fidelity-map.png": _fidelity_map,
        **{f"images/work-precision-{top}.png": _work_precision(top)
           for top in ("fig3", "fig11", "stiff")},
    }
    if _chromium() is None:  # said once, before any command runs for a screenshot
        log.warning("docs images: chromium not found: it screenshots the reports (Debian: bash "
                    "scripts/install-system-packages.sh; %s=0 builds without images)", ENV)
        for name in ("images/validate-report.png", "images/nightly-report.png"):
            out[name] = _placeholder("failed: chromium not found")
            del makers[name]
    with tempfile.TemporaryDirectory(prefix="tippetop-docs-") as tmp:
        for name, make in makers.items():
            t0 = time.perf_counter()
            try:
                out[name] = make(root, Path(tmp))
            except ImageError as exc:
                log.warning("docs image %s: %s (%s=0 builds without images)", name, exc, ENV)
                out[name] = _placeholder(f"failed: {exc}")
            else:
                log.info("docs image %s made in %.1f s", name, time.perf_counter() - t0)
        t0 = time.perf_counter()
        try:
            out.update(_probe_images(root, Path(tmp)))
        except ImageError as exc:
            log.warning("docs probe figures and table: %s (%s=0 builds without images)", exc,
                        ENV)
            _PROBE_TABLE["text"] = f"*(the table was not built: {exc})*"
            out.update({name: _placeholder(f"failed: {exc}") for name in IMAGES
                        if name.startswith("images/probe-")})
        else:
            took = time.perf_counter() - t0
            for name in IMAGES:  # one command made them all, and the table
                if name.startswith("images/probe-"):
                    log.info("docs image %s made in %.1f s", name, took)
            log.info("docs probe figures and table made in %.1f s", took)
    log.info("docs images made in %.1f s", time.perf_counter() - start)
    return out


def _probe_images(root: Path, tmp: Path) -> dict[str, bytes]:
    """``tippetop probe --out``'s figures, and the table over the integrators (kept aside).

    A probe outside its tolerance exits 1: a finding the page shows, not a failed build.
    """
    import json

    folder = tmp / "probes"
    _run([_tippetop(), "probe", "--out", str(folder)], root, ok=(0, 1))
    out = {}
    for name in _probe_names():
        png = folder / f"{name}.png"
        if not png.is_file():
            raise ImageError(f"tippetop probe --out wrote no {png.name}")
        out[f"images/probe-{name}.png"] = png.read_bytes()
    results = {}
    for integ in PROBE_INTEGRATORS:
        out_text = _run([_tippetop(), "probe", "--integrator", integ, "--json"], root,
                        ok=(0, 1))
        results[integ] = json.loads(out_text)
    _PROBE_TABLE["text"] = probe_table(results)
    return out


def probe_table(results: dict[str, dict]) -> str:
    """A markdown table: each probe quantity's exact value and its value under each integrator.

    A value outside its tolerance is marked **x**; a run that failed says so.
    """
    integs = list(results)
    first = next(iter(results.values()))
    version = first["results"][0]["version"] if first["results"] else "?"
    rows: dict[tuple[str, str, str], dict[str, dict]] = {}
    for integ, res in results.items():
        for r in res["results"]:
            rows.setdefault((r["probe"], r["mode"], r["quantity"]), {})[integ] = r

    def cell(r: dict | None) -> str:
        if r is None:
            return "-"
        if r["value"] is None:
            return "failed"
        text = f"{r['value']:.4g}"
        return text if r["passed"] else f"**{text} x**"

    head = ("| probe | mode | quantity | exact | tolerance | "
            + " | ".join(integs) + " |\n|" + "---|" * (5 + len(integs)) + "\n")
    body = []
    for (probe, mode, q), by in rows.items():
        any_row = next(iter(by.values()))
        exact = "-" if any_row["exact"] is None else f"{any_row['exact']:.4g}"
        body.append(f"| {probe} | {mode} | {q} ({any_row['unit']}) | {exact} | "
                    f"{any_row['tolerance']:g} | "
                    + " | ".join(cell(by.get(i)) for i in integs) + " |")
    steps = sorted({f"{r['timestep_s']:g}" for r in first["results"]})
    n = {i: sum(r["passed"] for r in results[i]["results"]) for i in integs}
    total = len(first["results"])
    summary = ", ".join(f"{i} {n[i]} of {total}" for i in integs)
    return (f"MuJoCo {version}, each probe at its own step ({', '.join(steps)} s), built with "
            f"this page; within tolerance: {summary}. **x**: outside the tolerance.\n\n"
            + head + "\n".join(body) + "\n")


def on_page_markdown(markdown: str, page: object, **kwargs: object) -> str:
    """Put today's probe table where a page writes ``{{ probe_table }}``."""
    if PROBE_TABLE_MARKER not in markdown:
        return markdown
    text = _PROBE_TABLE["text"] or (f"*(not built: {ENV}=0; the table is made by "
                                    "`tippetop probe --integrator NAME` for each integrator)*")
    return markdown.replace(PROBE_TABLE_MARKER, text)


def _tippetop() -> str:
    here = Path(sys.executable).parent / "tippetop"
    found = str(here) if here.is_file() else shutil.which("tippetop")
    if not found:
        raise ImageError("the tippetop command is not installed (pip install -e .)")
    return found


def command_env(root: Path | None = None) -> dict[str, str]:
    """The environment the commands run in: this process's, with the docs build's own cache.

    ``TIPPETOP_CACHE`` decides where a command keeps its runs, its history
    (``history.sqlite``), its compiled code (``numba/``, unless ``NUMBA_CACHE_DIR`` is set: the
    user's choice, kept) and its managed environments (``envs/``): here ``root``/:data:`CACHE`.

    Args:
        root: The repository (default :data:`ROOT`).
    """
    return dict(os.environ, TIPPETOP_CACHE=str(((root or ROOT) / CACHE).resolve()))


def _run(args: list[str], cwd: Path, ok: tuple[int, ...] = (0,),
         env: dict[str, str] | None = None) -> str:
    """Run a command with the docs build's own cache; its stdout (ImageError if it fails)."""
    try:
        proc = subprocess.run(args, cwd=cwd, env=command_env() | (env or {}), capture_output=True,
                              text=True, timeout=TIMEOUT_S, check=False)
    except subprocess.TimeoutExpired as exc:
        raise ImageError(f"`{_show(args)}` took over {TIMEOUT_S} s") from exc
    if proc.returncode not in ok:
        lines = [ln for ln in (proc.stderr + proc.stdout).splitlines() if ln.strip()]
        why = lines[-1].strip() if lines else "no output"
        raise ImageError(f"`{_show(args)}` exited {proc.returncode}: {why}")
    return proc.stdout


def _show(args: list[str]) -> str:
    return " ".join(["tippetop", *args[1:]] if args and args[0].endswith("tippetop") else args)


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return None


def _screenshot(html: Path, crop_height: int, tmp: Path) -> bytes:
    from PIL import Image

    if not html.is_file():
        raise ImageError(f"{html.name} was not written")
    chromium = _chromium()
    if chromium is None:
        raise ImageError("chromium not found")
    png = tmp / f"{html.parent.name}.png"
    # a profile, a config and a cache folder of its own in the temporary folder: none of the
    # user's (~/.config/chromium, ~/.cache/chromium-headless)
    own = tmp / "chromium"
    _run([chromium, "--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
          f"--user-data-dir={own / 'profile'}", f"--window-size={WINDOW[0]},{WINDOW[1]}",
          f"--screenshot={png}", html.as_uri()], tmp,
         env={"XDG_CONFIG_HOME": str(own / "config"), "XDG_CACHE_HOME": str(own / "cache")})
    if not png.is_file():
        raise ImageError(f"chromium wrote no screenshot of {html}")
    with Image.open(png) as im:
        shot = im.convert("RGB").crop((0, 0, im.width, min(crop_height, im.height)))
    return _png(shot)


def _validate_report(root: Path, tmp: Path) -> bytes:
    out = tmp / "validate-report"
    # exit 1: a check departs (the file's own contact does not turn this top over)
    _run([_tippetop(), "validate", VALIDATE_MODEL, "--no-tune", "--out", str(out)], root,
         ok=(0, 1))
    return _screenshot(out / "report.html", CROP_VALIDATE, tmp)


def _nightly_report(root: Path, tmp: Path) -> bytes:
    out = tmp / "nightly-report"
    # exit 1 is a regression: the report shows it, as it would to a user
    _run([_tippetop(), "nightly", "--profile", "quick", "--cases", NIGHTLY_CASES, "--out",
          str(out)], tmp, ok=(0, 1))
    return _screenshot(out / "report.html", CROP_NIGHTLY, tmp)


def _render_strip(root: Path, tmp: Path) -> bytes:
    import imageio.v3 as iio
    from PIL import Image

    mp4 = tmp / "fig3.mp4"
    _run([_tippetop(), "render", "fig3", "--engines", "mujoco,ode", "--speed", "1", "--fps",
          "10", "--set", "run.t_end_s=4", "--size", "320x240", "--max-frames", "90", "--out",
          str(mp4)], tmp)
    frames = iio.imread(mp4)
    if len(frames) < STRIP_FRAMES:
        raise ImageError(f"the video has {len(frames)} frames, fewer than {STRIP_FRAMES}")
    picks = [round(i * (len(frames) - 1) / (STRIP_FRAMES - 1)) for i in range(STRIP_FRAMES)]
    h, w = frames[0].shape[:2]
    cols = 3
    rows = -(-STRIP_FRAMES // cols)
    strip = Image.new("RGB", (w * cols, h * rows), "white")
    for k, i in enumerate(picks):
        strip.paste(Image.fromarray(frames[i]), ((k % cols) * w, (k // cols) * h))
    return _png(strip)


def _contact_window(root: Path, tmp: Path) -> bytes:
    png = tmp / "contact-window.png"
    _run([sys.executable, "-m", "tippetop.compare.report.window", str(png)], root)
    if not png.is_file():
        raise ImageError("the window figure was not written")
    return png.read_bytes()


def _contact_lift(root: Path, tmp: Path) -> bytes:
    png = tmp / "contact-lift.png"
    _run([sys.executable, "-m", "tippetop.compare.report.lift", str(png), str(root)], root)
    if not png.is_file():
        raise ImageError("the lift figure was not written")
    return png.read_bytes()


def _fidelity_map(root: Path, tmp: Path) -> bytes:
    png = tmp / "fidelity-map.png"
    _run([sys.executable, "-m", "tippetop.compare.report.fidelity", str(root / FIDELITY_RESULTS),
          str(png)], root)
    if not png.is_file():
        raise ImageError("the fidelity figure was not written")
    return png.read_bytes()


def _work_precision(top: str) -> Callable[[Path, Path], bytes]:
    def make(root: Path, tmp: Path) -> bytes:
        png = tmp / f"work-precision-{top}.png"
        _run([sys.executable, "-m", "tippetop.compare.studies.work_precision_report",
              str(root / WORK_PRECISION_RESULTS), top, str(png)], root)
        if not png.is_file():
            raise ImageError(f"the work-precision figure of {top} was not written")
        return png.read_bytes()

    return make


def _placeholder(text: str) -> bytes:
    from PIL import Image, ImageDraw

    im = Image.new("RGB", (960, 120), (238, 238, 238))
    ImageDraw.Draw(im).text((16, 50), text[:150], fill=(80, 80, 80))
    return _png(im)


def _png(im: object) -> bytes:
    buf = io.BytesIO()
    im.save(buf, format="PNG", optimize=True)  # type: ignore[attr-defined]
    return buf.getvalue()
