"""Every fenced code block of docs/*.md runs as written.

A block's language says what it is: ``sh``/``bash`` blocks run in bash (``-e``: the first failing
command fails the block), ``console`` blocks run their ``$ `` lines and their other lines are the
output they print, ``python`` blocks run standalone (``python3 -c``, no state from another block).
The other languages (``toml``, ``json``, ``csv``, ``text``) are data or output and are not run, but
every block must say its language, so that none escapes as "not code".

Each block runs in a fresh temporary folder holding a copy of the repository's ``examples/`` (the
files the blocks name, by the paths a reader at the repository root types) and an empty
``docs/images/`` (where the animation block writes); ``frogsim``, ``python`` and ``python3`` there
are this interpreter running this checkout (``python3 -m frogsim``).

An HTML comment on the line before a block changes what is done with it:

* ``<!-- test: not runnable: REASON -->``: not run (it needs hardware, a display, a server left
  running); the reason is required, and this test lists every such block.
* ``<!-- test: slow -->``: run, under the ``slow`` marker (``-m "not slow"`` leaves it out).
* ``<!-- test: synopsis -->``: a command's form with placeholders (``SCENARIO``, ``N``): the command
  must exist and take every option the block names (shell), or the block must compile and every
  ``frogsim.NAME(..., key=...)`` it calls must exist with those keywords (Python).
* ``<!-- test: output of the block above -->``: what the block above prints, compared with what it
  printed when run here (see :func:`assert_output`).
"""
from __future__ import annotations

import ast
import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted((ROOT / "docs").glob("*.md"))
FENCE = re.compile(r"^```([\w-]*)\n(.*?)^```$", re.S | re.M)
MARK = re.compile(r"<!-- test: (.*?) -->\n\Z")
RUN = {"sh", "bash", "console", "python"}
DATA = {"toml", "json", "csv", "text"}
#: pages another change is rewriting: their untagged blocks are known (see the xfail below)
UNTAGGED_PENDING: set = set()
#: the run's wall time in a printed line ("396 model runs in 2.5 s"): not a number the page can hold
WALL_TIME = re.compile(r"\bin \d+(?:\.\d+)? s\b")


@dataclass
class Block:
    page: str
    line: int
    lang: str
    text: str
    mark: str | None
    output: str | None = None          # the output block that follows it, if marked so

    @property
    def id(self) -> str:
        return f"{self.page}:{self.line}"


def read_blocks() -> list[Block]:
    out = []
    for path in PAGES:
        text = path.read_text()
        page_blocks = []
        for m in FENCE.finditer(text):
            mark = MARK.search(text[:m.start()])
            page_blocks.append(Block(path.name, text.count("\n", 0, m.start()) + 1, m.group(1), m.group(2),
                                     mark.group(1).strip() if mark else None))
        for k, b in enumerate(page_blocks):
            if b.mark == "output of the block above":
                assert k > 0 and page_blocks[k - 1].lang in RUN, f"{b.id}: no block above to compare with"
                page_blocks[k - 1].output = b.text
        out += page_blocks
    return out


BLOCKS = read_blocks()
MARKS = {"slow", "synopsis", "output of the block above"}


def test_the_pages_have_blocks_of_every_kind():
    langs = {b.lang for b in BLOCKS}
    assert {"sh", "python", "console", "toml"} <= langs, langs
    assert sum(b.lang in RUN for b in BLOCKS) >= 15


@pytest.mark.parametrize("block", [b for b in BLOCKS if b.mark], ids=lambda b: b.id)
def test_every_mark_is_known_and_a_block_not_run_says_why(block):
    if block.mark.startswith("not runnable"):
        reason = block.mark.removeprefix("not runnable").lstrip(":").strip()
        assert len(reason.split()) >= 3, f"{block.id}: 'not runnable' needs its reason"
        assert block.lang in RUN, f"{block.id}: only code is marked not runnable"
    else:
        assert block.mark in MARKS, f"{block.id}: unknown mark {block.mark!r}"


@pytest.mark.parametrize("page", [p.name for p in PAGES])
def test_every_block_says_its_language(page, request):
    if page in UNTAGGED_PENDING:
        request.applymarker(pytest.mark.xfail(strict=True, reason=f"docs/{page} is being rewritten elsewhere; its "
                                                                  "blocks get their languages there"))
    untagged = [b.id for b in BLOCKS if b.page == page and b.lang not in RUN | DATA]
    assert not untagged, f"blocks without a known language ({sorted(RUN | DATA)}): {untagged}"


# --- running them ---------------------------------------------------------------------------------
def folder(tmp_path: Path) -> tuple[Path, dict]:
    """A fresh working folder as the repository root looks to a reader, and the environment."""
    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    (tmp_path / "docs" / "images").mkdir(parents=True)
    bin_dir = tmp_path / ".bin"
    bin_dir.mkdir()
    for name, run in (("frogsim", f'"{sys.executable}" -m frogsim'), ("python", f'"{sys.executable}"'),
                      ("python3", f'"{sys.executable}"')):
        (bin_dir / name).write_text(f'#!/bin/sh\nexec {run} "$@"\n')
        (bin_dir / name).chmod(0o755)
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}", MPLBACKEND="Agg",
               PYTHONPATH=os.pathsep.join([str(ROOT / "src")] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    return tmp_path, env


def run(argv, cwd, env, what) -> str:
    p = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=900)
    out = p.stdout + p.stderr
    assert p.returncode == 0, f"{what} exits {p.returncode}:\n{out[-3000:]}"
    return out


def printed_lines(out: str) -> list[str]:
    """The lines a terminal would keep: each line's text after its last carriage return (progress
    bars redraw themselves), without trailing spaces; empty lines dropped."""
    lines = [line.rsplit("\r", 1)[-1].rstrip() for line in out.split("\n")]
    return [line for line in lines if line]


def assert_output(page_text: str, out: str, what: str) -> None:
    """The page's lines appear in the printed output, in order (lines the page leaves out, such as
    progress bars, may come between them). A page line is a whole printed line; one ending in
    "..." is the start of one, the rest left out; a long printed line may be wrapped over several
    page lines. The run's wall time ("in 2.5 s") is the one number not compared."""
    got = [WALL_TIME.sub("in <t> s", line) for line in printed_lines(out)]
    want = [WALL_TIME.sub("in <t> s", line.rstrip()) for line in page_text.splitlines() if line.strip()]
    k, rest = 0, None                       # the printed line being matched, and what of it is left
    for line in want:
        elided = line.endswith("...")
        piece = line[:-3].rstrip(", ") if elided else line
        while True:
            if rest is None:
                assert k < len(got), f"{what}: the page's line {line!r} is not in the output:\n" + "\n".join(got)
                rest, k = got[k], k + 1
                fresh = True
            else:
                fresh = False
            if elided and rest.startswith(piece):
                rest = None
                break
            if rest == piece:
                rest = None
                break
            if rest.startswith(piece + " "):          # wrapped on the page
                rest = rest[len(piece) + 1:]
                break
            assert fresh, f"{what}: the page's line {line!r} does not go on the printed line; printed: {rest!r}"
            rest = None


def console_commands(text: str) -> list[str]:
    cmds = [line[2:] for line in text.splitlines() if line.startswith("$ ")]
    assert cmds, "a console block without a '$ ' line"
    return cmds


def run_block(block: Block, tmp_path: Path) -> str:
    cwd, env = folder(tmp_path)
    what = f"docs/{block.id} ({block.lang})"
    if block.lang == "python":
        return run([sys.executable, "-c", block.text], cwd, env, what)
    if block.lang == "console":
        out = ""
        for cmd in console_commands(block.text):
            out += run(["bash", "-e", "-c", cmd], cwd, env, f"{what}: $ {cmd}")
        expected = "\n".join(line for line in block.text.splitlines() if not line.startswith("$ "))
        assert_output(expected, out, what)
        return out
    return run(["bash", "-e", "-c", block.text], cwd, env, what)


def _param(b: Block):
    marks = [pytest.mark.slow] if b.mark == "slow" else []
    return pytest.param(b, id=b.id, marks=marks)


RUNNABLE = [b for b in BLOCKS if b.lang in RUN and b.mark in (None, "slow")]


@pytest.mark.parametrize("block", [_param(b) for b in RUNNABLE])
def test_the_block_runs_as_written(block, tmp_path):
    out = run_block(block, tmp_path)
    if block.output is not None:
        assert_output(block.output, out, f"docs/{block.id}'s output block")


# --- synopses -------------------------------------------------------------------------------------
def _subparsers(parser):
    import argparse
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


@pytest.mark.parametrize("block", [b for b in BLOCKS if b.mark == "synopsis"], ids=lambda b: b.id)
def test_a_synopsis_names_a_command_and_options_that_exist(block):
    if block.lang == "python":
        tree = ast.parse(block.text)
        import inspect

        import frogsim
        calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute)
                 and isinstance(n.func.value, ast.Name) and n.func.value.id == "frogsim"]
        assert calls, block.id
        for c in calls:
            fn = getattr(frogsim, c.func.attr)
            params = inspect.signature(fn).parameters
            for kw in c.keywords:
                assert kw.arg in params, f"{block.id}: frogsim.{c.func.attr} takes no {kw.arg!r}"
        return
    from frogsim.cli import build_parser
    commands = _subparsers(build_parser())
    text = block.text.replace("\\\n", " ")
    lines = [line for line in text.splitlines() if line.strip()]
    # a synopsis is one command; an indented line goes on with it
    words = shlex.split(" ".join(lines).replace("[", " ").replace("]", " ").replace("|", " "))
    words = words[3:] if words[:3] == ["python3", "-m", "frogsim"] else words[1:] if words[0] == "frogsim" else None
    assert words, f"{block.id}: not a frogsim command"
    sub = commands[words[0]]
    known = {s for a in sub._actions for s in a.option_strings}
    named = {w.split("=")[0] for w in words if w.startswith("--")}
    assert named and named <= known, f"{block.id}: options the command does not take: {sorted(named - known)}"


def test_the_blocks_not_run_are_few_and_listed():
    skipped = [(b.id, b.mark) for b in BLOCKS if b.mark and b.mark.startswith("not runnable")]
    # what this test does not run, written out: a new one must be added here on purpose
    assert {i.split(":")[0] for i, _ in skipped} <= {"robot.md", "sweeps.md", "firmware.md", "control.md"}, skipped
    assert len(skipped) <= 4, skipped
