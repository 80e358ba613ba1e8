"""Output folders: who owns one, what is in it, and ``manifest.json``.

The rule (README, "Output folders")
    A folder belongs to the command that first wrote into it (``simulate``, ``swim``, ``fit``,
    ``reproduce``, ``design``, ``compare``); its ``manifest.json`` says which.

    - Another command refuses to write there (exit 2, nothing written); with ``--overwrite`` it
      first deletes the files the manifest lists, then writes its own: the folder changes hands.
    - ``simulate``, ``swim``, ``fit`` and ``compare`` hold one run: running again into the same folder
      needs ``--overwrite``, which deletes the previous run's files first (no stale file of the
      old run survives, e.g. an animation the new run does not make).
    - ``reproduce`` and ``design`` hold studies: a later run may add studies the folder does not
      have yet; a study already there is replaced only with ``--overwrite`` (only that study's
      files and summary section). ``summary.json`` holds the sections of the studies present.
    - A folder with files but no readable manifest (an older frogsim, or someone else's) is
      refused if it holds any file the run would write, unless ``--overwrite``.

    Every check happens before the first write. ``manifest.json`` is written first with
    ``"status": "running"`` (so even an interrupted run owns its folder) and rewritten at the end
    with ``"complete"``, ``"interrupted"`` (Ctrl-C, SIGINT) or ``"failed"`` (an error:
    :func:`ended_status`); a run of the same command may replace an interrupted or failed one
    without ``--overwrite``.

manifest.json
    ``command``, ``command_line`` (and ``argv``), ``cwd``, ``frogsim_version``, ``started`` and
    ``finished`` (UTC, ISO 8601), ``status``, ``scenario`` (name, ``sha256`` over the contents of
    every input file, and ``inputs``: role, path and SHA-256 of each file read: scenario file,
    parameter set, joint-angle tables), ``files`` (name, bytes, SHA-256 of each file written),
    for study commands ``studies`` (study -> its files and summary keys) and ``runs`` (each
    invocation that wrote into the folder).
"""
from __future__ import annotations

import json
import os
import shlex
from datetime import datetime, timezone
from pathlib import Path

from frogsim.errors import ScenarioError

MANIFEST = "manifest.json"
SUMMARY = "summary.json"
FORMAT = 1
STUDY_COMMANDS = ("reproduce", "design")


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _sha256(path: Path) -> str | None:
    from frogsim.sweep.spec import file_sha256
    return file_sha256(path)


def read_manifest(folder) -> dict | None:
    """The manifest of an output folder, or None if it has none (or it cannot be read)."""
    try:
        data = json.loads((Path(folder) / MANIFEST).read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and isinstance(data.get("command"), str) else None


def scenario_record(name: str, inputs: list[dict]) -> dict:
    """The manifest's "scenario" entry: its name, inputs and one SHA-256 over their contents."""
    from frogsim.sweep.spec import inputs_sha256
    return {"name": name, "sha256": inputs_sha256(inputs), "inputs": inputs}


def scenario_inputs(scenario, source) -> list[dict]:
    """Described input files of a loaded scenario (see :func:`frogsim.sweep.spec.input_files`)."""
    from frogsim.sweep.spec import describe_inputs, input_files
    return describe_inputs(input_files(scenario, source))


def shipped_inputs() -> list[dict]:
    """Described shipped scenarios and parameter sets (what the registered studies read)."""
    from frogsim.scenario.load import PARAMS_DIR, SCENARIOS_DIR
    from frogsim.sweep.spec import describe_inputs
    files = [(f"parameters {p.stem}", p) for p in sorted(PARAMS_DIR.glob("*.toml"))]
    files += [(f"scenario {p.stem}", p) for p in sorted(SCENARIOS_DIR.glob("*.toml"))]
    return describe_inputs(files)


def ended_status(exc: BaseException) -> str:
    """The manifest status of a run that stopped on ``exc``: "interrupted" for Ctrl-C (and a
    SystemExit from a signal handler), "failed" for an error."""
    return "interrupted" if isinstance(exc, (KeyboardInterrupt, SystemExit)) else "failed"


class OutputFolder:
    """One run's claim on an output folder (see the module docstring for the rule).

    ``check()`` raises ScenarioError (nothing written) if the run may not write there;
    ``begin()`` clears what an allowed overwrite replaces and writes the running manifest;
    ``finish()`` writes the final one. ``files`` are the names the run plans to write (for a
    study command: ``studies`` maps each study to its file names), relative to the folder (a
    name may lie in a subfolder: "NAME/NAME.ino"). ``folders`` are subfolders whose files other
    tools write for the run (a compiler's objects): every file found there at the end that was
    not there when the run began is listed in the manifest too, so that a later ``--overwrite``
    removes it.

    Removing a replaced run's files: each file its manifest lists (never one outside the folder,
    never one it does not list), then every subfolder left empty; files another hand put in such
    a subfolder stay, and :attr:`left` names them (the command line warns).
    """

    def __init__(self, out, command: str, argv: list[str], overwrite: bool = False,
                 files: list[str] | None = None, studies: dict[str, list[str]] | None = None,
                 scenario: dict | None = None, folders: list[str] | None = None):
        self.out = Path(out)
        self.command = command
        self.argv = list(argv)
        self.overwrite = overwrite
        self.studies = dict(studies or {})
        self.files = list(files or []) + [f for names in self.studies.values() for f in names]
        self.folders = list(folders or [])
        self.scenario = scenario
        self.previous = None
        self.kept_studies: dict = {}
        self.started = None
        self.left: list[str] = []
        self._remove: list[str] = []
        self._found_before: set = set()

    def keep(self, name: str) -> None:
        """Leave ``name`` in place when an allowed overwrite clears the folder (a resumable
        store, such as a gait search's study.db, that the run goes on from)."""
        self._remove = [f for f in self._remove if f != name]

    # --- before anything is written -------------------------------------------------------------
    def _refuse(self, why: str):
        raise ScenarioError("--out", str(self.out), why)

    def check(self) -> None:
        out = self.out
        if out.exists() and not out.is_dir():
            self._refuse("exists and is not a directory")
        planned = set(self.files) | {SUMMARY, MANIFEST}
        if not out.exists():
            return
        prev = read_manifest(out)
        self.previous = prev
        if prev is None:
            clash = sorted(f for f in planned if (out / f).exists())
            if clash and not self.overwrite:
                self._refuse(f"holds files of another run ({', '.join(clash[:4])}"
                             f"{', ...' if len(clash) > 4 else ''}) and no {MANIFEST}; use --overwrite to "
                             "replace them, or another --out")
            self._remove = [f for f in clash if f != MANIFEST]
            return
        pcmd = prev["command"]
        done = prev.get("status") == "complete"
        listed = [f["name"] if isinstance(f, dict) else str(f) for f in prev.get("files", [])]
        if pcmd != self.command:
            if not self.overwrite:
                self._refuse(f"holds the outputs of `frogsim {pcmd}` ({prev.get('command_line', '')!s}); "
                             f"a folder belongs to one command: use another --out, or --overwrite to "
                             "replace them")
            self._remove = listed + [SUMMARY]
            self.previous = None
            return
        if self.command in STUDY_COMMANDS:
            have = dict(prev.get("studies", {}))
            again = [s for s in self.studies if s in have]
            if again and done and not self.overwrite:
                self._refuse(f"holds the studies {', '.join(again)} from an earlier `frogsim {pcmd}` run; "
                             "use --overwrite to replace them, or another --out")
            self.kept_studies = {s: v for s, v in have.items() if s not in self.studies}
            self._remove = [f for s in again for f in have[s].get("files", [])]
            return
        if done and not self.overwrite:
            self._refuse(f"holds the outputs of an earlier `frogsim {pcmd}` run ({prev.get('command_line', '')!s}, "
                         f"{prev.get('finished', prev.get('started', '?'))}); use --overwrite to replace them, "
                         "or another --out")
        self._remove = listed + [SUMMARY]
        self.previous = None

    # --- writing --------------------------------------------------------------------------------
    def _inside(self, name: str) -> Path | None:
        """out/name if ``name`` is a relative path that stays inside the folder (through no
        symbolic link out of it), else None."""
        rel = Path(name)
        if rel.is_absolute() or not rel.parts or ".." in rel.parts:
            return None
        path = self.out / rel
        try:
            if not path.resolve().is_relative_to(self.out.resolve()):
                return None
        except (OSError, RuntimeError):
            return None
        return path

    def _files_under(self, folder: str) -> list[str]:
        """The files under subfolder ``folder`` (relative names, sorted)."""
        base = self._inside(folder)
        if base is None or not base.is_dir() or base.is_symlink():
            return []
        return sorted(p.relative_to(self.out).as_posix() for p in base.rglob("*") if p.is_file())

    def begin(self) -> None:
        """Make the folder, delete what this run replaces (the files listed, then the subfolders
        they leave empty), and claim it (manifest "running")."""
        self.out.mkdir(parents=True, exist_ok=True)
        emptied = set()
        for name in dict.fromkeys(self._remove):
            path = self._inside(name)
            if path is not None and path.is_file():
                path.unlink()
                emptied.update(d for d in path.parents if d != self.out and d.is_relative_to(self.out))
        for d in sorted(emptied, key=lambda p: len(p.parts), reverse=True):
            if d.is_dir() and not d.is_symlink() and not any(d.iterdir()):
                d.rmdir()
        tops = {d.relative_to(self.out).parts[0] for d in emptied}
        self.left = [f for top in sorted(tops) for f in self._files_under(top)]
        self._found_before = {f for folder in self.folders for f in self._files_under(folder)}
        self.started = _now()
        self._write("running", [])

    def previous_summary(self) -> dict:
        """The summary sections of the studies this run keeps (study commands), else {}."""
        if not self.kept_studies:
            return {}
        try:
            old = json.loads((self.out / SUMMARY).read_text())
        except (OSError, ValueError):
            return {}
        keys = {k for v in self.kept_studies.values() for k in v.get("summary_keys", [])}
        return {k: v for k, v in old.items() if k in keys} if isinstance(old, dict) else {}

    def finish(self, status: str = "complete", summaries: dict[str, list[str]] | None = None,
               extra_files: list[str] = ()) -> Path:
        """Write the final manifest: the files present of those planned (plus ``extra_files``),
        each with its size and SHA-256; ``summaries`` maps each study run to its summary keys."""
        made = [f for folder in self.folders for f in self._files_under(folder) if f not in self._found_before]
        names = [f for f in dict.fromkeys(self.files + list(extra_files) + made + [SUMMARY])
                 if (self.out / f).is_file()]
        studies = None
        if self.command in STUDY_COMMANDS:
            studies = dict(self.kept_studies)
            for s, keys in (summaries or {}).items():
                studies[s] = {"files": [f for f in self.studies.get(s, []) if (self.out / f).is_file()],
                              "summary_keys": list(keys)}
            studies = {s: studies[s] for s in sorted(studies)}
            for v in self.kept_studies.values():
                names += [f for f in v.get("files", []) if (self.out / f).is_file() and f not in names]
        self._write(status, names, studies)
        return self.out / MANIFEST

    def _write(self, status: str, names: list[str], studies: dict | None = None) -> None:
        from frogsim import __version__
        from frogsim._files import write_json
        line = shlex.join(["frogsim"] + self.argv)
        runs = []
        if self.previous is not None and self.command in STUDY_COMMANDS:
            runs = [r for r in self.previous.get("runs", []) if isinstance(r, dict)]
        this = {"command_line": line, "started": self.started, "studies": list(self.studies) or None,
                "frogsim_version": __version__, "status": status}
        if status != "running":
            this["finished"] = _now()
        data = {
            "frogsim_manifest": FORMAT,
            "command": self.command,
            "command_line": line,
            "argv": ["frogsim"] + self.argv,
            "cwd": os.getcwd(),
            "frogsim_version": __version__,
            "started": self.started,
            "finished": this.get("finished"),
            "status": status,
            "scenario": self.scenario,
            "files": [{"name": n, "bytes": (self.out / n).stat().st_size, "sha256": _sha256(self.out / n)}
                      for n in names],
        }
        if self.command in STUDY_COMMANDS:
            data["studies"] = studies if studies is not None else dict(self.kept_studies)
            data["runs"] = runs + [this]
        write_json(self.out / MANIFEST, data)
