"""Folders this package writes (a run's results, a report, a comparison) and nothing else.

A folder is ours when it carries our `manifest.json`: the kind of folder, the run's
status and every file we wrote in it with its size and SHA-256. We write only into a
folder that is new, empty, or ours; replacing our earlier results removes exactly the
files the manifest lists (a report folder inside a run's folder included) and leaves
any other file alone. A listed file changed since we wrote it, or an earlier run that
never finished (its files were never listed), is replaced only with `force`. Readers
(`report`, `compare`) check a run's folder against its manifest before they trust it.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import platoon_sumo
from platoon_sumo.errors import PlatoonSumoError

MANIFEST = "manifest.json"
TOOL = "platoon-sumo"
RUNNING, COMPLETE, FAILED, INTERRUPTED = "running", "complete", "failed", "interrupted"
#: A run folder made for a file beside the results (`add_file`) before any run wrote it.
NO_RUN = "no run"
#: Kinds of folder we write.
KINDS = ("run", "report", "comparison", "study")


class FolderError(PlatoonSumoError):
    """A folder we were asked to write into, or read from, that we must not use: it is
    not ours, changed since we wrote it, or its run did not finish."""


@dataclass
class OwnedFolder:
    """A folder claimed for writing; `finish` lists what was written in its manifest."""

    path: Path
    kind: str
    foreign: frozenset[Path] = field(default_factory=frozenset)

    def finish(self, status: str) -> None:
        files = {
            rel: _fingerprint(self.path / rel)
            for rel in _files(self.path)
            if Path(rel) not in self.foreign and rel != MANIFEST
        }
        _write_manifest(self.path, self.kind, status, files)


def claim(
    path: str | Path, kind: str, writes: frozenset[str] | None = None, force: bool = False
) -> OwnedFolder:
    """Make `path` ours for a new `kind` folder: create it, or replace our earlier
    results in it; raise FolderError (nothing written, nothing removed) otherwise.

    `writes` names the top-level files and folders we are about to write: other files
    may stay beside ours (all files must go when it is None)."""
    assert kind in KINDS, kind
    folder = Path(path)
    manifest = _open(folder)
    ours: set[Path] = set()
    if manifest is not None:
        if manifest["kind"] != kind:
            raise FolderError(
                f"{folder}: holds a {TOOL} {manifest['kind']}, not a {kind}; nothing was "
                "written (choose another folder)"
            )
        ours = _earlier_files(folder, manifest, writes, force)
    foreign = frozenset(
        Path(rel) for rel in _files(folder) if folder / rel not in ours and rel != MANIFEST
    )
    clash = sorted(str(rel) for rel in foreign if writes is None or rel.parts[0] in writes)
    if clash:
        raise FolderError(
            f"{folder}: holds files {TOOL} did not write where it writes ({', '.join(clash[:3])}"
            f"{' ...' if len(clash) > 3 else ''}); nothing was written (move them away)"
        )
    for file in sorted(ours, reverse=True):
        file.unlink(missing_ok=True)
        _prune(file.parent, stop=folder)
    _write_manifest(folder, kind, RUNNING, {})
    return OwnedFolder(folder, kind, foreign)


def add_file(folder: str | Path, name: str) -> Path:
    """A new, empty file for one more picture beside a run's results (a laser scan):
    never one that exists (`name` gets `_2`, `_3`, ... when taken), never deleting a file.

    `folder` is created if needed; a new or empty one gets a run manifest with status
    NO_RUN, so that a later run still claims it, which then keeps the file as one not
    listed. A folder of the user's (no manifest) just gets the file; a report,
    comparison or study folder is refused, since replacing those removes every file."""
    folder = Path(folder)
    manifest = read_manifest(folder) if folder.is_dir() else None
    if manifest is not None and manifest["kind"] != "run":
        raise FolderError(
            f"{folder}: holds a {TOOL} {manifest['kind']}; nothing was written (choose "
            "the run's folder or another one)"
        )
    if manifest is None and not (folder.is_dir() and any(folder.iterdir())):
        _open(folder)
        _write_manifest(folder, "run", NO_RUN, {})
    stem, suffix = Path(name).stem, Path(name).suffix
    for n in range(1, 10_000):
        path = folder / (name if n == 1 else f"{stem}_{n}{suffix}")
        try:
            path.open("xb").close()
        except FileExistsError:
            continue
        except OSError as exc:
            raise FolderError(f"{folder}: cannot write {path.name}: {exc.strerror}") from None
        return path
    raise FolderError(f"{folder}: {name} and 9998 numbered copies exist; nothing was written")


@dataclass
class StudyFolder:
    """A study's folder: its runs' folders (each a run folder of its own) and the study's
    tables; `finish` lists the study's own files in its manifest."""

    path: Path
    study_sha256: str

    def finish(self, status: str) -> None:
        files = {rel: _fingerprint(self.path / rel) for rel in _files(self.path) if rel != MANIFEST}
        _write_manifest(self.path, "study", status, files, {"study_sha256": self.study_sha256})


def open_study_folder(path: str | Path, study_sha256: str) -> StudyFolder:
    """A new or empty folder for a study, or the folder of the same study run before
    (nothing removed: its finished runs are kept and skipped); FolderError for a folder
    that is not ours or holds something else."""
    folder = Path(path)
    manifest = _open(folder)
    if manifest is not None and manifest["kind"] != "study":
        raise FolderError(f"{folder}: holds a {TOOL} {manifest['kind']}, not a study")
    if manifest is not None and manifest.get("study_sha256") != study_sha256:
        raise FolderError(
            f"{folder}: holds the results of another study (or of this study file or its "
            "scenario before they changed); nothing was written (choose another --out)"
        )
    files = manifest["files"] if manifest is not None else {}
    _write_manifest(folder, "study", RUNNING, files, {"study_sha256": study_sha256})
    return StudyFolder(folder, study_sha256)


def _open(folder: Path) -> dict[str, Any] | None:
    """Create `folder` if needed and return our manifest in it (None for a new or empty
    folder); FolderError for a file, an unwritable folder or one of someone else's."""
    if folder.exists() and not folder.is_dir():
        raise FolderError(f"{folder}: is a file, not a folder (choose another --out)")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FolderError(f"{folder}: cannot create the folder: {exc.strerror}") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise FolderError(f"{folder}: the folder is not writable (choose another --out)")
    manifest = read_manifest(folder)
    if manifest is None and any(folder.iterdir()):
        raise FolderError(
            f"{folder}: the folder is not empty and was not written by {TOOL} "
            f"(no {MANIFEST}); nothing was written (choose a new or empty folder with --out)"
        )
    return manifest


def read_manifest(folder: Path) -> dict[str, Any] | None:
    """Our manifest of `folder`, or None when the folder has none of ours."""
    try:
        data = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("tool") != TOOL or data.get("kind") not in KINDS:
        return None
    if not isinstance(data.get("files"), dict):
        return None
    return data


def check_finished_run(folder: str | Path) -> list[str]:
    """Raise FolderError unless `folder` holds a run that finished, with every file as
    the run wrote it; return warnings (files whose content changed at the same size)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FolderError(f"{folder}: no such results folder")
    manifest = read_manifest(folder)
    if manifest is None or manifest["kind"] != "run":
        raise FolderError(
            f"{folder}: not the results of a {TOOL} run (no {MANIFEST}; results written "
            "before manifests existed have none: run the scenario again)"
        )
    status = manifest.get("status")
    if status != COMPLETE:
        why = {
            RUNNING: "the run never finished (killed?)",
            FAILED: "the run failed (see FAILED.txt)",
            INTERRUPTED: "the run was interrupted (see FAILED.txt)",
            NO_RUN: "no run wrote here yet (only pictures were added, e.g. a scan)",
        }.get(str(status), f"the run's status is {status!r}")
        raise FolderError(f"{folder}: {why}; its tables are incomplete")
    warnings = []
    for rel, expected in sorted(manifest["files"].items()):
        actual = folder / rel
        if not actual.is_file():
            raise FolderError(f"{folder}: {rel} is missing; the results are incomplete")
        size = actual.stat().st_size
        if size != expected.get("bytes"):
            raise FolderError(
                f"{folder}: {rel} has {size} bytes, the run wrote {expected.get('bytes')} "
                "(truncated or edited); run the scenario again"
            )
        if _sha256(actual) != expected.get("sha256"):
            warnings.append(f"{folder}: {rel} was edited after the run wrote it")
    return warnings


def _earlier_files(
    folder: Path, manifest: dict[str, Any], writes: frozenset[str] | None, force: bool
) -> set[Path]:
    """The files an earlier run (report, comparison) wrote in `folder`, its reports'
    included, once checked to be as written (or `force`); FolderError otherwise."""
    status = manifest.get("status")
    if status == RUNNING and not force:
        raise FolderError(
            f"{folder}: holds an earlier {TOOL} {manifest['kind']} that never finished "
            "(killed?), whose files are not listed; nothing was written (remove the folder, "
            "or --force to replace it)"
        )
    listed = manifest["files"]
    if not force:
        for rel, expected in sorted(listed.items()):
            actual = folder / rel
            if actual.is_file() and _fingerprint(actual) != expected:
                raise FolderError(
                    f"{folder}: {rel} changed since {TOOL} wrote it; nothing was written "
                    "(move it away, or --force to replace the earlier results)"
                )
    files = {folder / rel for rel in listed} | {folder / MANIFEST}
    for sub in sorted(folder.iterdir()):  # a run's reports go with the run
        report = read_manifest(sub) if sub.is_dir() else None
        if report is not None and report["kind"] == "report":
            files |= _earlier_files(sub, report, None, force)
    if status == RUNNING:  # forced: every file under a name we write is taken for ours
        for rel in _files(folder):
            if writes is None or Path(rel).parts[0] in writes:
                files.add(folder / rel)
    return files


def _prune(directory: Path, stop: Path | None = None) -> None:
    """Remove `directory` and its parents up to `stop` while they are empty."""
    while directory != stop and directory.is_dir() and not any(directory.iterdir()):
        directory.rmdir()
        directory = directory.parent


def _files(folder: Path) -> Iterable[str]:
    """Every file under `folder` (relative, '/'-separated), nested folders of ours
    (a report in a run's folder) left out: they list their own."""
    for root, dirs, names in os.walk(folder):
        here = Path(root)
        dirs[:] = sorted(d for d in dirs if read_manifest(here / d) is None)
        for name in sorted(names):
            yield (here / name).relative_to(folder).as_posix()


def _fingerprint(path: Path) -> dict[str, Any]:
    return {"bytes": path.stat().st_size, "sha256": _sha256(path)}


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _write_manifest(
    folder: Path, kind: str, status: str, files: dict[str, Any], extra: dict[str, Any] | None = None
) -> None:
    data = {
        "tool": TOOL,
        "version": platoon_sumo.__version__,
        "kind": kind,
        "status": status,
        "files": files,
        **(extra or {}),
    }
    tmp = folder / (MANIFEST + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n", encoding="utf-8")
    os.replace(tmp, folder / MANIFEST)
