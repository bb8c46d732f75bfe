"""Every command the documentation shows is run, so an example that stops working fails.

The convention (docs/development/docs.md says it for writers):

- Shell commands are shown only in fenced blocks of language ``console``. A command line starts
  with ``$ `` (a line ending in `` \\`` goes on on the next); the other lines of the block are
  the output of the command above them: each one shown must appear in what the command prints
  (stdout or stderr, whitespace collapsed; a line ``...`` stands for lines left out).
- A trailing ``# ...`` comment is for the reader (a command's cost); ``exit status N`` in it is
  the status the command must end with (default 0).
- ``<!-- docs-test: slow -->`` on the line before the fence marks a block that takes more than
  about 20 s: it runs in the slow suite (``pytest -m slow``).
- Commands that install or that CI itself runs (``pip``, ``apt-get``, ``uv``, ``bash
  scripts/...``, ``pytest``, ``ruff``, ``properdocs``) are not run here: each must be a
  command ``.ci/run`` runs (``sudo`` and quiet flags aside), so the docs install exactly what CI
  tests. ``properdocs build --strict`` itself is run by :func:`test_docs_build_strict`.
- Blocks of other languages (toml, xml, json, text, ...) are data, not commands; ``bash``,
  ``sh`` and ``shell`` blocks are refused, so that no command escapes the test.

Each block runs in a fresh working folder (links to the repository's ``examples/``, ``models/``
and ``tests/``) with a private ``TIPPETOP_CACHE`` shared by the session (the first command pays
the compilation). A block whose commands another block already ran is checked against that run's
output. What the commands write into the working folder must be ignored by git (``.gitignore``),
since a reader runs them in the repository. A failure names the doc file and
the line.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shlex
import shutil
import sqlite3
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOC_FILES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
CI_RUN = ROOT / ".ci" / "run"

#: Repository folders linked into each block's working folder (the docs' inputs).
INPUTS = ("examples", "models", "tests")

#: Commands that install, or that CI runs itself: checked against .ci/run, never run here.
CI_PROGRAMS = {"pip", "pip3", "apt-get", "apt", "uv", "pytest", "ruff", "properdocs", "mkdocs",
               "zensical", "venv", ".", "source"}
#: Flags that change only how much a CI command prints.
QUIET_FLAGS = {"-q", "-qq", "--quiet", "--no-progress"}
#: Fence languages that would hold commands outside the convention.
SHELL_LANGS = {"bash", "sh", "shell", "zsh", "shell-session", "shellsession", "sh-session"}

FAST_TIMEOUT_S = 600
SLOW_TIMEOUT_S = 3600

FENCE = re.compile(r"^(?P<indent>\s*)(?P<fence>`{3,}|~{3,})\s*(?P<info>[^`]*)$")
MARKER = re.compile(r"<!--\s*docs-test:\s*(?P<flags>[^>]*?)\s*-->")
EXIT = re.compile(r"exit status (\d+)")


@dataclass
class Command:
    """One ``$`` command of a console block and the output lines shown under it."""

    line: int
    text: str
    shown: list[str] = field(default_factory=list)

    @property
    def expected_status(self) -> int:
        """The exit status the trailing comment names (0 if none)."""
        comment = _comment(self.text)
        m = EXIT.search(comment) if comment else None
        return int(m.group(1)) if m else 0


@dataclass
class Block:
    """A ``console`` block: where it is, its commands, whether it is slow."""

    path: Path
    line: int
    commands: list[Command]
    slow: bool

    @property
    def where(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


@dataclass
class Fence:
    """Any fenced code block: its language, where it starts, its lines and the marker above."""

    path: Path
    line: int
    lang: str
    body: list[tuple[int, str]]
    marker: str


def _fences(path: Path) -> list[Fence]:
    lines = path.read_text(encoding="utf-8").splitlines()
    out: list[Fence] = []
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence = len(m.group("indent")), m.group("fence")
        lang = (m.group("info").split() or [""])[0].lower().lstrip(".{")
        prev = lines[i - 1] if i > 0 else ""
        marker = MARKER.search(prev)
        start, body = i + 1, []
        i += 1
        while i < len(lines):
            closing = lines[i].strip()
            if closing.startswith(fence[0] * len(fence)) and not closing.strip(fence[0]):
                break
            body.append((i + 1, lines[i][indent:] if lines[i][:indent].isspace() else
                         lines[i].lstrip()))
            i += 1
        out.append(Fence(path, start, lang, body, marker.group("flags") if marker else ""))
        i += 1
    return out


def _block(f: Fence) -> Block:
    commands: list[Command] = []
    pending: Command | None = None
    for no, text in f.body:
        if pending is not None:  # a continuation line
            pending.text += "\n" + text
            if not text.rstrip().endswith("\\"):
                pending = None
            continue
        if text.startswith("$ "):
            cmd = Command(no, text[2:])
            commands.append(cmd)
            if text.rstrip().endswith("\\"):
                pending = cmd
        elif text.strip():
            if not commands:
                raise AssertionError(f"{f.path.relative_to(ROOT)}:{no}: output before the "
                                     "first `$ ` command of a console block")
            if text.strip() != "...":
                commands[-1].shown.append(text)
    if not commands:
        raise AssertionError(f"{f.path.relative_to(ROOT)}:{f.line}: a console block without "
                             "a `$ ` command")
    flags = set(f.marker.split())
    unknown = flags - {"slow"}
    if unknown:
        raise AssertionError(f"{f.path.relative_to(ROOT)}:{f.line - 1}: unknown docs-test "
                             f"flag(s) {sorted(unknown)}")
    return Block(f.path, f.line, commands, "slow" in flags)


def _comment(text: str) -> str:
    """The trailing ``# ...`` comment of a command (outside quotes), or ''."""
    quote, i = None, 0
    while i < len(text):
        ch = text[i]
        if quote:
            if ch == quote:
                quote = None
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or text[i - 1].isspace()):
            return text[i + 1:].strip()
        i += 1
    return ""


def _words(command: str) -> list[str]:
    """A command's words, normalised to compare docs with .ci/run: no comment, no ``sudo``,
    no variable assignments in front, ``python -m X`` as ``X``, no quiet flags, no
    redirections."""
    words = shlex.split(command.replace("\\\n", " "), comments=True)
    out: list[str] = []
    skip = False
    for w in words:
        if skip:
            skip = False
            continue
        if re.fullmatch(r"\d*>>?|<", w):  # a redirection whose target is the next word
            skip = True
            continue
        if re.fullmatch(r"\d*>>?\S+|\d*>&\d+|<\S+", w) or w in QUIET_FLAGS:
            continue
        out.append(w)
    while out and (out[0] == "sudo" or re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*=.*", out[0])):
        out.pop(0)
    if len(out) >= 3 and re.fullmatch(r"python(3(\.\d+)?)?", out[0]) and out[1] == "-m":
        out = out[2:]
    return out


def _is_ci(command: str) -> bool:
    words = _words(command)
    if not words:
        return False
    return words[0] in CI_PROGRAMS or (words[0] == "bash" and len(words) > 1
                                       and words[1].startswith("scripts/"))


def _ci_commands() -> list[list[str]]:
    """Every simple command of .ci/run, normalised as :func:`_words` does."""
    text = CI_RUN.read_text(encoding="utf-8").replace("\\\n", " ")
    out: list[list[str]] = []
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        for part in re.split(r"&&|\|\||;|\|", line):
            try:
                words = _words(part)
            except ValueError:  # an unbalanced quote split by the regex: not a command we show
                continue
            if words:
                out.append(words)
    return out


FENCES = [f for path in DOC_FILES for f in _fences(path)]
BLOCKS = [_block(f) for f in FENCES if f.lang == "console"]


def _params(slow: bool) -> list[object]:
    params = []
    for b in BLOCKS:
        if b.slow != slow or all(_is_ci(c.text) for c in b.commands):
            continue
        marks = [pytest.mark.slow] if slow else []
        params.append(pytest.param(b, id=b.where, marks=marks))
    return params


def test_every_shell_block_is_a_console_block() -> None:
    bad = [f"{f.path.relative_to(ROOT)}:{f.line}: ```{f.lang} block: show commands in a "
           "```console block with `$ ` prompts" for f in FENCES if f.lang in SHELL_LANGS]
    bad += [f"{f.path.relative_to(ROOT)}:{f.line}: a ```{f.lang or '(no language)'} block "
            "holds `$ ` lines: make it a ```console block" for f in FENCES
            if f.lang != "console" and any(t.startswith("$ ") for _, t in f.body)]
    bad += [f"{f.path.relative_to(ROOT)}:{f.line - 1}: a docs-test marker above a "
            f"```{f.lang} block (only console blocks are run)" for f in FENCES
            if f.marker and f.lang != "console"]
    assert not bad, "\n".join(bad)


def test_the_docs_show_commands() -> None:
    # the README's quick start and the guide's examples, at least
    assert any(b.path.name == "README.md" for b in BLOCKS)
    assert sum(len(b.commands) for b in BLOCKS) >= 20


def test_install_and_ci_commands_are_the_ones_ci_runs() -> None:
    """The docs' install, test and docs-build commands are exactly ones .ci/run runs."""
    ci = _ci_commands()
    missing = [f"{b.path.relative_to(ROOT)}:{c.line}: `{c.text.split(' #')[0].strip()}` is "
               "not a command .ci/run runs" for b in BLOCKS for c in b.commands
               if _is_ci(c.text) and _words(c.text) not in ci]
    assert not missing, "\n".join(missing)


def test_readme_links_resolve() -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    bad = []
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"[a-z]+://|#|mailto:", target):
            continue
        if not (ROOT / target.split("#")[0]).exists():
            bad.append(target)
    assert not bad, f"README.md links to missing files: {bad}"



def _hook(name: str, needs: str):
    """docs/hooks/NAME.py as a module, loaded by its path as properdocs loads it (a hook's name
    may shadow a standard module: math); skipped without ``needs``, the docs extra's."""
    import importlib.util

    pytest.importorskip(needs, reason="the docs extra: pip install -e '.[docs]'")
    spec = importlib.util.spec_from_file_location(f"tippetop_docs_{name}_hook",
                                                  ROOT / "docs" / "hooks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _math_hook():
    """docs/hooks/math.py as a module."""
    return _hook("math", "latex2mathml")


def _math_headings() -> list[tuple[str, str]]:
    """(where, heading line) of every heading of the docs with a formula in it."""
    out = []
    for path in sorted((ROOT / "docs").rglob("*.md")):
        fence = None
        for no, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            m = FENCE.match(line)
            if m and (fence is None or m.group("fence").startswith(fence)):
                fence = m.group("fence")[:3] if fence is None else None
            elif fence is None and re.match(r"#{1,6}\s", line) and re.search(r"\$|\\\(", line):
                out.append((f"{path.relative_to(ROOT)}:{no}", line))
    return out


def test_the_math_hook_leaves_no_raw_latex_in_headings() -> None:
    """A formula in a heading shows as MathML in the table of contents (the sidebars) and as
    text in the page's title, never as raw ``\\(\\xi\\)``: every such heading of the docs,
    rendered as the site renders it (toc, arithmatex), then through the hook."""
    markdown = pytest.importorskip("markdown")
    pytest.importorskip("pymdownx.arithmatex")
    toc_mod = pytest.importorskip("properdocs.structure.toc")
    hook = _math_hook()
    headings = _math_headings()
    assert any(where.startswith("docs/physics/theory.md") for where, _ in headings), headings
    # a page whose first heading has a formula too (its title), and \( \) as well as $ $
    lines = [r"# The \(\xi_\pm\) page", *(h for _, h in headings), r"### With \(a < b\)"]
    md = markdown.Markdown(extensions=["toc", "pymdownx.arithmatex"],
                           extension_configs={"pymdownx.arithmatex": {"generic": True}})
    content = md.convert("\n\n".join(lines))
    toc = toc_mod.get_toc(md.toc_tokens)
    page = type("Page", (), {})()
    page.file = type("File", (), {"src_uri": "test.md"})()
    page.toc, page.title = toc, toc.items[0].title
    assert "\\(" in page.title and "\\(" in toc.items[0].children[0].title  # as MkDocs has them

    html = hook.on_page_content(content, page=page)

    def entries(items):
        for item in items:
            yield item.title
            yield from entries(item.children)

    titles = list(entries(toc))
    assert len(titles) == len(lines)
    bad = [t for t in titles if "\\(" in t or "\\[" in t or "<math" not in t]
    assert not bad, f"table-of-contents entries with raw LaTeX or no MathML: {bad}"
    assert page.title == "The ξ± page"
    assert "\\(" not in html and html.count("<math") == len(lines)
    assert hook.title_text(r"\(a < b\)") == "a&lt;b"  # text, escaped for the HTML


@pytest.fixture(scope="module")
def docs_env(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    env = dict(os.environ)
    env["TIPPETOP_CACHE"] = str(tmp_path_factory.mktemp("tippetop-cache"))
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env.pop("NUMBA_CACHE_DIR", None)
    return env


#: Output of blocks already run, by their commands (blocks repeated across pages run once).
_RUNS: dict[tuple[str, ...], list[tuple[int, str]]] = {}


def _run_block(block: Block, env: dict[str, str], workdir: Path) -> None:
    key = tuple(" ".join(_words(c.text)) for c in block.commands)
    if key not in _RUNS:
        for name in INPUTS:
            (workdir / name).symlink_to(ROOT / name, target_is_directory=True)
        timeout = SLOW_TIMEOUT_S if block.slow else FAST_TIMEOUT_S
        results = []
        for c in block.commands:
            if _is_ci(c.text):
                results.append((0, ""))
                continue
            try:
                proc = subprocess.run(["bash", "-c", c.text], cwd=workdir, env=env,
                                      capture_output=True, text=True, timeout=timeout,
                                      check=False)
            except subprocess.TimeoutExpired:
                pytest.fail(f"{block.path.relative_to(ROOT)}:{c.line}: `{c.text}` took over "
                            f"{timeout} s")
            results.append((proc.returncode, proc.stdout + proc.stderr))
            if proc.returncode != c.expected_status:
                tail = "\n".join(proc.stderr.strip().splitlines()[-5:]
                                 or proc.stdout.strip().splitlines()[-5:])
                pytest.fail(f"{block.path.relative_to(ROOT)}:{c.line}: `{c.text}` exited "
                            f"{proc.returncode}, expected {c.expected_status}:\n{tail}")
        _check_ignored(block, workdir)
        _RUNS[key] = results
    for c, (_, output) in zip(block.commands, _RUNS[key], strict=True):
        printed = [" ".join(line.split()) for line in output.splitlines()]
        for shown in c.shown:
            want = " ".join(shown.split())
            assert any(want in line for line in printed), (
                f"{block.path.relative_to(ROOT)}:{c.line}: `{c.text}` did not print the line "
                f"shown under it:\n  {shown}\nit printed:\n" + "\n".join(printed[:40]))


def _check_ignored(block: Block, workdir: Path) -> None:
    """What the block wrote into the working folder is ignored by git in the repository."""
    written = [p for p in workdir.iterdir() if p.name not in INPUTS]
    if not written or shutil.which("git") is None:
        return
    paths = [p.name + ("/" if p.is_dir() else "") for p in written]
    proc = subprocess.run(["git", "check-ignore", "--no-index", "--stdin", "-v", "-n"],
                          cwd=ROOT, input="\n".join(paths) + "\n", capture_output=True,
                          text=True, check=False)
    unignored = [ln.split("\t", 1)[1] for ln in proc.stdout.splitlines()
                 if ln.startswith("::\t")]
    assert not unignored, (f"{block.where}: the commands write {unignored} into the working "
                           "folder; add them to .gitignore")


@pytest.mark.parametrize("block", _params(slow=False))
def test_docs_commands(block: Block, docs_env: dict[str, str], tmp_path: Path) -> None:
    _run_block(block, docs_env, tmp_path)


@pytest.mark.parametrize("block", _params(slow=True))
def test_docs_commands_slow(block: Block, docs_env: dict[str, str], tmp_path: Path) -> None:
    _run_block(block, docs_env, tmp_path)


def _images_hook():
    """docs/hooks/images.py as a module."""
    return _hook("images", "mkdocs")


def _tree(folder: Path) -> dict[str, tuple[int, int, str]]:
    """Everything under ``folder``: relative path -> (size, mtime in ns, sha256 of a file)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        st = p.lstat()
        digest = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "folder"
        out[str(p.relative_to(folder))] = (st.st_size, st.st_mtime_ns, digest)
    return out


def _seed_user_cache(folder: Path) -> dict[str, tuple[int, int, str]]:
    """A user's ``TIPPETOP_CACHE`` as a docs build may find it, and its :func:`_tree`: a history
    of one nightly (written by the project's own history code), a cached run, compiled code."""
    from tippetop.compare.nightly.history import Measure, RunInfo, append_run

    append_run(RunInfo(kind="nightly", started="2026-01-02T03:04:05+00:00", profile="quick",
                       argv=["tippetop", "nightly", "--profile", "quick"]),
               [Measure(case="paper/fig3", engine="ode", metric="t_flip_s", value=1.5)],
               folder / "history.sqlite")
    (folder / "ab").mkdir()
    (folder / "ab" / "abcdef.json").write_text('{"a user\'s": "cached run"}\n')
    (folder / "numba" / "0123456789abcdef").mkdir(parents=True)
    (folder / "numba" / "0123456789abcdef" / "user.nbi").write_bytes(b"compiled")
    return _tree(folder)


def _unchanged(folder: Path, before: dict[str, tuple[int, int, str]]) -> str:
    """What differs in ``folder`` from ``before`` ('' when nothing does)."""
    after = _tree(folder)

    def how(name: str) -> str:
        return "new" if name not in before else "gone" if name not in after else "changed"

    return "\n".join(f"  {name}: {how(name)}" for name in sorted(before.keys() | after.keys())
                     if before.get(name) != after.get(name))


def _history_runs(path: Path) -> list[str]:
    """The argv of every run in a history file (none when there is no file)."""
    if not path.is_file():
        return []
    con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    try:
        return [argv for (argv,) in con.execute("SELECT argv FROM runs ORDER BY id")]
    finally:
        con.close()


def _build(env: dict[str, str], site: Path) -> str:
    """The README's command, as a newcomer runs it (no config file named: properdocs.yml is
    found by its name; no variable to hide a notice); only the site folder is a temporary one.
    What it printed; the build must pass."""
    proc = subprocess.run(["properdocs", "build", "--strict", "--site-dir", str(site)],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=900,
                          check=False)
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, log[-3000:]
    return log


#: Run by :func:`test_the_picture_commands_keep_to_the_docs_cache` through the images hook:
#: appends a run to the default history (as ``nightly`` does) and says where its cache is.
_WHERE = """
import json, os, sys
from tippetop.compare.nightly.history import RunInfo, append_run, history_path, timestamp_now
from tippetop.models.resources import user_cache_dir
from tippetop.reference_ode import NUMBA_CACHE_DIR
append_run(RunInfo(kind="nightly", started=timestamp_now(), argv=["docs-hook-test"]), [])
json.dump({"cache": str(user_cache_dir()), "history": str(history_path()),
           "numba": None if NUMBA_CACHE_DIR is None else str(NUMBA_CACHE_DIR),
           "numba_env": os.environ.get("NUMBA_CACHE_DIR")}, open(sys.argv[1], "w"))
"""


@pytest.mark.parametrize("user_numba", [False, True], ids=["default-numba", "user-numba"])
def test_the_picture_commands_keep_to_the_docs_cache(user_numba: bool, tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """docs/hooks/images.py runs its commands (``tippetop validate``, ``nightly``, ``render``)
    with the docs build's own cache, ``build/docs-cache``: a command run as they are, with the
    user's ``TIPPETOP_CACHE`` set, appends its run to the docs cache's history and compiles
    there, and leaves the user's cache as it was. A ``NUMBA_CACHE_DIR`` the user set is kept."""
    hook = _images_hook()
    user = tmp_path / "user-cache"
    before = _seed_user_cache(user)
    monkeypatch.setenv("TIPPETOP_CACHE", str(user))
    if user_numba:
        monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "user-numba"))
    else:
        monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    repo = tmp_path / "repo"  # not the repository's own build/docs-cache
    monkeypatch.setattr(hook, "ROOT", repo)
    out = tmp_path / "where.json"
    hook._run([sys.executable, "-c", _WHERE, str(out)], tmp_path)
    changed = _unchanged(user, before)
    assert not changed, f"the docs build's command changed the user's TIPPETOP_CACHE:\n{changed}"
    where = json.loads(out.read_text())
    docs_cache = (repo / "build" / "docs-cache").resolve()
    assert where["cache"] == str(docs_cache)
    assert where["history"] == str(docs_cache / "history.sqlite")
    assert _history_runs(docs_cache / "history.sqlite") == ['["docs-hook-test"]']
    if user_numba:
        assert where["numba"] is None
        assert where["numba_env"] == str(tmp_path / "user-numba")
    else:
        assert where["numba_env"] is None
        assert Path(where["numba"]).parent == docs_cache / "numba"


def test_chromium_keeps_out_of_the_users_home(tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """The reports' screenshot: Chromium gets a profile, a config and a cache folder in the
    build's temporary folder, and writes nothing into the user's home (~/.config/chromium,
    ~/.cache/chromium-headless)."""
    hook = _images_hook()
    if hook._chromium() is None:
        pytest.skip("chromium not installed (bash scripts/install-system-packages.sh)")
    home = tmp_path / "home"
    home.mkdir()
    monkeypatch.setenv("HOME", str(home))
    for name in ("XDG_CONFIG_HOME", "XDG_CACHE_HOME", "XDG_DATA_HOME"):
        monkeypatch.delenv(name, raising=False)
    page = tmp_path / "report" / "report.html"
    page.parent.mkdir()
    page.write_text("<!doctype html><p>a report</p>\n")
    work = tmp_path / "work"
    work.mkdir()
    png = hook._screenshot(page, 100, work)
    assert png.startswith(b"\x89PNG")
    wrote = sorted(str(q.relative_to(home)) for q in home.glob("*/*"))
    assert not list(home.iterdir()), f"chromium wrote into the home: {wrote}"


def test_docs_build_strict(docs_env: dict[str, str], tmp_path: Path) -> None:
    """The site builds with warnings as errors (links, anchors, the API pages' docstrings),
    printing only INFO lines (no notice, no deprecation: a newcomer reads what it prints), and
    leaves the user's ``TIPPETOP_CACHE`` as it was (the hooks in this process: API links,
    formulas, glossary). The images are left out here (TIPPETOP_DOCS_IMAGES=0): CI builds them
    in its own step, and :func:`test_docs_build_with_pictures_leaves_the_users_cache` in the
    slow suite."""
    pytest.importorskip("properdocs", reason="the docs extra: pip install -e '.[docs]'")
    pytest.importorskip("mkdocstrings_handlers.python", reason="pip install -e '.[docs]'")
    user = tmp_path / "user-cache"
    before = _seed_user_cache(user)
    env = dict(docs_env, TIPPETOP_DOCS_IMAGES="0", TIPPETOP_CACHE=str(user))
    # as in a fresh clone: the API hook's links (build/docs-api) made by this build (a first
    # build once failed where a second passed: mkdocstrings left out a path not there yet)
    shutil.rmtree(ROOT / "build" / "docs-api", ignore_errors=True)
    log = _build(env, tmp_path / "site")
    changed = _unchanged(user, before)
    assert not changed, f"the docs build changed the user's TIPPETOP_CACHE:\n{changed}"
    # every line it prints is an INFO line
    not_info = [ln for ln in log.splitlines() if ln.strip() and not ln.startswith("INFO")]
    assert not not_info, "the docs build printed more than INFO lines:\n" + log[-3000:]
    assert "NO_MKDOCS_2_WARNING" not in log and "end of life" not in log
    assert (tmp_path / "site" / "index.html").is_file()
    assert (tmp_path / "site" / "images" / "nightly-report.png").is_file()
    # a formula in a heading: MathML in the tables of contents (both sidebars), text in the
    # page's <title>, never the raw \( \) (docs/hooks/math.py)
    raw = []
    for page in sorted((tmp_path / "site").rglob("*.html")):
        text = page.read_text(encoding="utf-8")
        labels = re.findall(r'<a [^>]*class="md-nav__link[^"]*"[^>]*>(.*?)</a>', text, re.S)
        labels += re.findall(r"<title>(.*?)</title>", text, re.S)
        raw += [f"{page.relative_to(tmp_path / 'site')}: {' '.join(label.split())}"
                for label in labels if "\\(" in label or "\\[" in label]
    assert not raw, "raw LaTeX in a table of contents or a title:\n" + "\n".join(raw)
    theory = (tmp_path / "site" / "physics" / "theory.html").read_text(encoding="utf-8")
    assert re.search(r'href="#the-gyroscopic[^"]*" class="md-nav__link">\s*<span[^>]*>\s*'
                     r"The gyroscopic balance condition and the <math", theory)
    _search_works_from_disk(tmp_path / "site", tmp_path)


def _search_works_from_disk(site: Path, tmp_path: Path) -> None:
    """The site's search box is there when a page is opened from disk with no network: no page
    loads a script from the network (Material's offline plugin loaded its iframe-worker shim
    from unpkg.com, and without it Material hides the box: issue 43), and in headless Chromium
    the search dialog of index.html is not hidden once its scripts have run, and a query
    finds a page."""
    remote = [p.name for p in site.rglob("*.html")
              if re.search(r'<script[^>]+src="https?://', p.read_text(encoding="utf-8"))]
    assert not remote, f"pages load a script from the network: {remote[:5]}"
    hook = _images_hook()
    chromium = hook._chromium()
    if chromium is None:
        pytest.skip("chromium not installed (bash scripts/install-system-packages.sh)")
    dom = subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu",
                          f"--user-data-dir={tmp_path / 'chromium'}",
                          "--virtual-time-budget=5000", "--dump-dom",
                          (site / "index.html").as_uri() + "?q=jellett"],
                         capture_output=True, text=True, timeout=120).stdout
    box = re.search(r'<div class="md-search"[^>]*>', dom)
    assert box is not None, dom[:2000]
    assert "hidden" not in box.group(0), f"the search box is hidden: {box.group(0)}"
    found = re.search(r'md-search-result__meta">\s*(\d+) matching document', dom)
    assert found and int(found.group(1)) >= 3, "no search results for 'jellett'"


@pytest.mark.slow
def test_docs_build_with_pictures_leaves_the_users_cache(docs_env: dict[str, str],
                                                         tmp_path: Path) -> None:
    """The build CI runs, its pictures made by real commands (docs/hooks/images.py), leaves
    the user's ``TIPPETOP_CACHE`` as it was, file for file: the picture's nightly is appended
    to the docs build's own history (``build/docs-cache``), not to the one ``tippetop history``
    shows the user."""
    pytest.importorskip("properdocs", reason="the docs extra: pip install -e '.[docs]'")
    pytest.importorskip("mkdocstrings_handlers.python", reason="pip install -e '.[docs]'")
    hook = _images_hook()
    if hook._chromium() is None:
        pytest.skip("chromium not installed (bash scripts/install-system-packages.sh)")
    user = tmp_path / "user-cache"
    before = _seed_user_cache(user)
    docs_history = ROOT / hook.CACHE / "history.sqlite"
    runs = len(_history_runs(docs_history))
    env = dict(docs_env, TIPPETOP_CACHE=str(user))
    env.pop(hook.ENV, None)
    log = _build(env, tmp_path / "site")
    not_made = [name for name in hook.IMAGES if f"docs image {name} made in" not in log]
    assert not not_made, f"pictures not made: {not_made}\n" + log[-3000:]
    changed = _unchanged(user, before)
    assert not changed, f"the docs build changed the user's TIPPETOP_CACHE:\n{changed}"
    added = _history_runs(docs_history)[runs:]
    assert len(added) == 1 and '"nightly"' in added[0], added
