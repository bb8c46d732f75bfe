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

import os
import re
import shlex
import shutil
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



def _math_hook():
    """docs/hooks/math.py as a module (by its path: its name would shadow the standard math)."""
    import importlib.util

    pytest.importorskip("latex2mathml", reason="the docs extra: pip install -e '.[docs]'")
    spec = importlib.util.spec_from_file_location("tippetop_docs_math_hook",
                                                  ROOT / "docs" / "hooks" / "math.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


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


def test_docs_build_strict(docs_env: dict[str, str], tmp_path: Path) -> None:
    """The site builds with warnings as errors (links, anchors, the API pages' docstrings),
    printing only INFO lines (no notice, no deprecation: a newcomer reads what it prints); the
    images are left out here (TIPPETOP_DOCS_IMAGES=0): CI builds them in its own step."""
    pytest.importorskip("properdocs", reason="the docs extra: pip install -e '.[docs]'")
    pytest.importorskip("mkdocstrings_handlers.python", reason="pip install -e '.[docs]'")
    env = dict(docs_env, TIPPETOP_DOCS_IMAGES="0")
    # as in a fresh clone: the API hook's links (build/docs-api) made by this build (a first
    # build once failed where a second passed: mkdocstrings left out a path not there yet)
    shutil.rmtree(ROOT / "build" / "docs-api", ignore_errors=True)
    # the README's command, as a newcomer runs it (no config file named: properdocs.yml is
    # found by its name; no variable to hide a notice); only the site folder is a temporary one
    proc = subprocess.run(["properdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=600,
                          check=False)
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, log[-3000:]
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
