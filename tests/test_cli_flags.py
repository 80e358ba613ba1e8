"""The README's flag table is the command line: every option of every command (read from argparse)
is in it, with the commands that have it, and its --help starts with the table's meaning; every row
of the table is an option those commands have. So one flag means one thing everywhere."""
from __future__ import annotations

import argparse
import re
from pathlib import Path

from frogsim.cli import build_parser

README = Path(__file__).resolve().parent.parent / "README.md"


def table() -> dict[str, tuple[str, set[str]]]:
    """flag -> (meaning, commands) of the README's "### Flags" table."""
    text = README.read_text()
    section = text[text.index("### Flags"):]
    rows = {}
    for line in section.splitlines()[1:]:
        if line.startswith("#"):
            break
        m = re.match(r"^\| `(--[a-z-]+)` \| (.*) \| (.*) \|$", line)
        if m:
            rows[m.group(1)] = (m.group(2).strip(), set(re.findall(r"`([a-z-]+)`", m.group(3))))
    return rows


def options() -> dict[str, dict[str, str]]:
    """flag -> {command: its help text} over every command's parser (hidden aliases left out)."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    out = {}
    for name, p in sub.choices.items():
        for a in p._actions:
            if a.help == argparse.SUPPRESS:
                continue
            for o in a.option_strings:
                if o not in ("-h", "--help"):
                    out.setdefault(o, {})[name] = a.help or ""
    for a in parser._actions:                         # frogsim's own: --version
        for o in a.option_strings:
            if o not in ("-h", "--help"):
                out.setdefault(o, {})["frogsim"] = a.help or ""
    return out


def test_every_option_is_in_the_table_with_its_commands_and_meaning():
    rows, opts = table(), options()
    assert rows, "no flag table in README.md"
    assert set(opts) == set(rows), (set(opts) ^ set(rows))
    for flag, by_command in opts.items():
        meaning, commands = rows[flag]
        assert commands == set(by_command), (flag, commands ^ set(by_command))
        for command, help_text in by_command.items():
            assert help_text.startswith(meaning), (flag, command, help_text, meaning)


def test_out_is_required_wherever_a_command_writes():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, p in sub.choices.items():
        for a in p._actions:
            if "--out" in a.option_strings:
                assert a.required and a.default is None, name


def test_help_of_every_command_renders(capsys):
    import pytest
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name in sub.choices:
        with pytest.raises(SystemExit) as exc:
            parser.parse_args([name, "--help"])
        assert exc.value.code == 0
        assert "--help" in capsys.readouterr().out


def test_out_says_what_this_command_writes():
    helps = options()["--out"]
    for command, text in helps.items():
        if command == "sweep":
            assert "results file" in text and "PNG" not in text, text
        elif command == "plot":
            assert "PNG file" in text and "results" not in text, text
        else:
            assert "folder" in text and "RESULTS.nc" not in text and "PNG" not in text, (command, text)
