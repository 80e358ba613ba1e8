"""The commands written in the comments of examples/*.toml work as written: each is read from the
file verbatim (continuation lines joined), every one is accepted by the command line's parser
(a missing --out exits 2), and the sweep examples' sweep-then-plot pairs run to their files."""
from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from frogsim.cli import build_parser, main

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"


def comment_commands(path: Path) -> list[list[str]]:
    """The ``frogsim ...`` commands of a file's comment lines, as argument lists (without
    "frogsim"); a line ending in a backslash goes on in the next comment line."""
    out, pending = [], None
    for line in path.read_text().splitlines():
        m = re.match(r"#\s+(.*?)\s*$", line)
        text = m.group(1) if m else None
        if pending is not None:
            if text is None:
                raise AssertionError(f"{path}: a command's continuation is not a comment line")
            pending += " " + text
        elif text is not None and text.startswith("frogsim "):
            pending = text
        else:
            continue
        if pending.endswith("\\"):
            pending = pending[:-1].rstrip()
            continue
        words = shlex.split(pending)
        assert words[0] == "frogsim"
        out.append(words[1:])
        pending = None
    return out


FILES = sorted(EXAMPLES.rglob("*.toml"))
COMMANDS = [(f.relative_to(ROOT).as_posix(), cmd) for f in FILES for cmd in comment_commands(f)]


def test_the_examples_hold_commands():
    names = {f for f, _ in COMMANDS}
    assert "examples/sweep-lhs-valves.toml" in names and "examples/sweep-source-saturation.toml" in names
    assert any(cmd[0] == "plot" for _, cmd in COMMANDS) and any(cmd[0] == "fit" for _, cmd in COMMANDS)


@pytest.mark.parametrize("where, cmd", COMMANDS, ids=[f"{f}:{c[0]}" for f, c in COMMANDS])
def test_every_example_command_is_accepted_as_written(where, cmd, capsys):
    try:
        build_parser().parse_args(cmd)
    except SystemExit as exc:
        pytest.fail(f"{where}: 'frogsim {' '.join(cmd)}' is refused (exit {exc.code}): "
                    f"{capsys.readouterr().err.strip()}")


@pytest.mark.parametrize("name", ["sweep-lhs-valves.toml", "sweep-source-saturation.toml"])
def test_the_sweep_examples_run_as_written(name, tmp_path, monkeypatch, capsys):
    # run from a folder that holds examples/ as the repository root does; the outputs go there
    (tmp_path / "examples").symlink_to(EXAMPLES, target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    cmds = comment_commands(EXAMPLES / name)
    assert [c[0] for c in cmds] == ["sweep", "plot"]
    for cmd in cmds:
        assert main(cmd + ["--quiet"]) == 0, capsys.readouterr().err
        out = Path(cmd[cmd.index("--out") + 1])
        assert out.is_file() and out.stat().st_size > 0, out
    assert Path(cmds[1][cmds[1].index("--out") + 1]).read_bytes()[:4] == b"\x89PNG"
