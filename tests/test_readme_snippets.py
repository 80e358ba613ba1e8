"""The README's TOML and Python blocks run as written: every TOML block is a scenario that loads (saved
under the file name its first comment line gives, so the Python blocks can name it), and the Python
blocks run in order in one namespace, in the folder holding those files."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parent.parent / "README.md"


def blocks(lang: str) -> list[str]:
    return re.findall(rf"^```{lang}\n(.*?)^```$", README.read_text(), flags=re.S | re.M)


def test_the_readme_has_toml_and_python_blocks():
    assert len(blocks("toml")) >= 3 and len(blocks("python")) >= 3


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """The README's TOML blocks, each saved as a file (its first line's name, else block-N.toml)."""
    out = tmp_path_factory.mktemp("readme")
    for k, text in enumerate(blocks("toml")):
        m = re.match(r"#\s*([\w.-]+\.toml)\b", text)
        (out / (m.group(1) if m else f"block-{k}.toml")).write_text(text)
    return out


def test_every_toml_block_is_a_scenario_that_loads(folder):
    import tomllib

    import frogsim
    files = sorted(folder.glob("*.toml"))
    assert len(files) == len(blocks("toml"))
    for f in files:
        raw = tomllib.loads(f.read_text())
        if "gait" in raw or "robot" in raw:
            frogsim.load_robot_scenario(str(f))
        else:
            frogsim.load_scenario(str(f))


def test_the_python_blocks_run_in_order(folder, monkeypatch):
    monkeypatch.chdir(folder)
    space: dict = {}
    for k, code in enumerate(blocks("python")):
        exec(compile(code, f"README.md python block {k + 1}", "exec"), space)
    # the closed-loop blocks' results (the names the README gives them)
    assert "r" in space and "r2" in space and "result" in space
