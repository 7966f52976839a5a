"""Where a run writes, and the promise that it never loses a user's data.

The output policy (docs/runs.md, "Runs: output folders, exit status, limits"):

* A run writes a **new** directory. Everything is first written into a hidden sibling
  ``.<name>.tmp-*`` and moved into place only when complete, so a failed or interrupted run
  leaves the previous result intact and no partial output.
* Every run directory holds a marker, :data:`MARKER`, listing the files the run wrote. An
  existing target is

  - used as is when it is an **empty** directory;
  - replaced only when it holds a marker (a previous run of this tool) **and** the user asked
    for it (``--overwrite`` or ``output.if_exists: overwrite``); only the files listed in the old
    marker are removed, and only if each is still the regular file, byte for byte, that run
    wrote (its SHA-256 is in the marker): a file the user changed, or put in place of one,
    stops the run before computing; anything the user added to the folder stays;
  - or, with ``output.if_exists: new``, left alone: the run goes to the first free numbered
    sibling ``<name>-2``, ``<name>-3``, ...;
  - refused in every other case (a regular file, a directory with files this tool did not
    write), before anything is computed.
* The final move cannot be cut by SIGINT/SIGTERM (they are held until it is complete): a
  result is either the previous one or the new one, never a mixture. Replacing a previous run
  is journaled (:data:`JOURNAL`, in the temporary folder, written before the first move): the
  old files are moved aside into the temporary folder, the new ones in, the new marker last. A
  run killed (SIGKILL, power cut of the process) during that sequence leaves the journal, and
  :func:`recover` (called by the next run into the same parent folder, and by
  ``nsm-continuation recover``) puts the previous run back, or finishes the new one when its
  marker is already in place: the folder then holds one complete run, never a mixture.
* Two runs cannot write the same target at once: a lock file ``.<name>.lock`` (created with
  ``O_EXCL``, holding JSON with the tool's name, the owner's PID and user id) is taken before
  computing. A lock is taken over only when it is provably ours and stale: a regular file, owned
  by the current user, holding that JSON, whose process is gone; anything else named like a lock
  is refused (never deleted).
* Each temporary folder holds :data:`TMP_MARKER` (the tool, the PID, the user id): the hidden
  temporary folder of a killed run (its process gone) is recognised by it and removed by the
  next run into the same parent folder (:func:`recover`); nothing else is.
* A run's output is never placed inside another run's temporary folder or inside a run folder
  (one holding :data:`MARKER`): the other run's clean-up or overwrite would remove it.
* Directories get mode 0755 and files 0644 (subject to the user's umask), like any other tool.

:meth:`OutputTarget.prepare` checks all of this, and that the location is creatable and writable
with free space, **before** the computation; failures are :class:`OutputError` (exit status 2)
with one line naming the path.
"""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
import signal
import stat
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from nsm_continuation import __version__
from nsm_continuation.cases.saved_runs import MARKER, read_marker, sha256
from nsm_continuation.core.errors import CaseError, short_text

#: free space required in the output location before a run starts
MIN_FREE_BYTES = 50 * 2**20
IfExists = Literal["error", "overwrite", "new"]


class OutputError(CaseError):
    """The output location cannot be used (exit status 2, nothing written)."""


#: marker of a temporary folder ``.<name>.tmp-*`` (who is writing it)
TMP_MARKER = ".nsm-continuation-tmp.json"
#: journal of a commit replacing a previous run, in the temporary folder
JOURNAL = ".nsm-continuation-commit.json"
#: where a commit keeps the previous run's files until the new ones are in place
ASIDE = ".previous"
#: a hidden temporary folder of a run: ``.<name>.tmp-<random>``
TMP_NAME = re.compile(r"^\.(.+)\.tmp-[^/]*$")
_TOOL = "nsm-continuation"


def _ownership(kind: str, **extra: Any) -> str:
    """The JSON text of a lock or a temporary folder's marker: what proves it is ours."""
    return json.dumps({"tool": _TOOL, "kind": kind, "pid": os.getpid(), "uid": os.getuid(),
                       **extra})


def _read_ours(path: Path, kind: str) -> dict | None:
    """The content of a lock or marker ``path`` of ``kind`` if it is provably ours: a regular
    file (not a symbolic link), owned by the current user, holding the JSON :func:`_ownership`
    writes; None otherwise (the caller never deletes it then)."""
    try:
        st = path.lstat()
        if not stat.S_ISREG(st.st_mode) or st.st_uid != os.getuid() or st.st_size > 4096:
            return None
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("tool") != _TOOL or data.get("kind") != kind \
            or not isinstance(data.get("pid"), int) or isinstance(data.get("pid"), bool) \
            or data.get("uid") != os.getuid():
        return None
    return data


def lock_text(pid: int | None = None) -> str:
    """What a lock of this tool holds (``pid``: the owner's, default this process)."""
    data = json.loads(_ownership("lock"))
    if pid is not None:
        data["pid"] = pid
    return json.dumps(data)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def previous_run_files(directory: Path) -> dict[str, str]:
    """The files a previous run wrote into ``directory`` (name -> SHA-256), each checked to be
    still that regular file; raises :class:`OutputError` naming the first one that is not (the
    user changed it, or put something else in its place): such a folder is never replaced."""
    marker = read_marker(directory)
    if marker is None:
        raise OutputError(f"output: {directory} already holds files that nsm-continuation did "
                          "not write; choose another --out (nothing was changed)")
    files: dict[str, str] = {}
    for name, digest in marker["files"].items():
        target = directory / str(name)
        if Path(str(name)).name != name or name in ("", ".", "..") or not isinstance(digest, str):
            raise OutputError(f"output: the marker of {directory} lists {name!r}, which is not a "
                              "file name this tool writes; nothing was changed")
        if not target.exists() and not target.is_symlink():
            continue  # already gone: nothing to remove
        if target.is_symlink() or not target.is_file() or sha256(target) != digest:
            raise OutputError(f"output: {target} is not the file the previous run wrote (changed "
                              "or replaced since); move it away or choose another --out "
                              "(nothing was changed)")
        files[name] = digest
    return files


@contextmanager
def _signals_held() -> Iterator[None]:
    """Hold SIGINT and SIGTERM until the block ends, then deliver them to the handlers that were
    in place (a Python handler runs in the main thread whichever thread the signal reached, so
    replacing the handler, not the thread's signal mask, is what defers it)."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    sigs = (signal.SIGINT, signal.SIGTERM)
    previous = {sig: signal.getsignal(sig) for sig in sigs}
    for sig in sigs:
        if previous[sig] is not signal.SIG_IGN:
            signal.signal(sig, lambda signum, frame: held.append(signum))
    try:
        yield
    finally:
        for sig in sigs:
            signal.signal(sig, previous[sig])
        for sig in dict.fromkeys(held):
            handler = previous[sig]
            if callable(handler):
                handler(sig, None)
            elif handler == signal.SIG_DFL:
                if sig == signal.SIGINT:
                    raise KeyboardInterrupt
                os.kill(os.getpid(), sig)


@dataclass
class OutputTarget:
    """One run's output directory, from the preflight check to the final move into place."""

    path: Path
    if_exists: IfExists = "error"
    tmp: Path | None = field(default=None, init=False)
    #: True once the result is in place (a signal arriving after that changes nothing)
    committed: bool = field(default=False, init=False)
    #: what :func:`recover` did in the parent folder before this run (one line each)
    recovered: list[str] = field(default_factory=list, init=False)
    _lock: Path | None = field(default=None, init=False)
    _created: list[Path] = field(default_factory=list, init=False)

    # ------------------------------------------------------------------ preflight
    def check(self) -> None:
        """Everything :meth:`prepare` checks, without creating anything (``validate``)."""
        self._guarded(self._check)

    def prepare(self) -> None:
        """Check the policy and the location, take the lock, create the temporary directory.

        Raises :class:`OutputError` naming the path; on error nothing is left behind.
        """
        self._guarded(self._prepare)

    def _guarded(self, step: Any) -> None:
        try:
            step()
        except (OSError, ValueError) as exc:  # a name too long, a NUL byte, an odd mount...
            self.abort()
            if isinstance(exc, OutputError):
                raise
            why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
            raise OutputError(f"output: cannot use {short_text(str(self.path))} ({why})"
                              ) from None

    def _check(self) -> None:
        self.path = Path(os.path.abspath(self.path))
        if self.if_exists == "new" and self._lock is None:
            self.path = self._first_free(self.path)
        self._check_policy()
        # the nearest existing ancestor must be a writable directory
        anc = self.path.parent
        while not anc.exists():
            if anc.is_symlink():
                raise OutputError(f"output: {anc} is a broken symbolic link")
            anc = anc.parent
        if not anc.is_dir():
            raise OutputError(f"output: {anc} exists and is not a directory")
        if not os.access(anc, os.W_OK | os.X_OK):
            raise OutputError(f"output: {anc} is not writable")
        try:
            free = shutil.disk_usage(anc).free
        except OSError:
            free = MIN_FREE_BYTES
        if free < MIN_FREE_BYTES:
            raise OutputError(f"output: only {free / 2**20:.1f} MiB free in {anc} (a run "
                              f"needs at least {MIN_FREE_BYTES // 2**20} MiB)")

    def _prepare(self) -> None:
        parent = Path(os.path.abspath(self.path)).parent
        if parent.is_dir():
            self.recovered = recover(parent)
        self._check()
        parent = self.path.parent
        missing = []
        anc = parent
        while not anc.exists():
            missing.append(anc)
            anc = anc.parent
        for d in reversed(missing):
            d.mkdir(mode=0o755)
            self._created.append(d)
        base, k = self.path, 1
        while not self._take_lock():  # "new": another run took this number meanwhile
            k += 1
            self.path = self._first_free(base, start=k)
            self._check_policy()
        self.tmp = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.tmp-", dir=parent))
        os.chmod(self.tmp, 0o755)
        (self.tmp / TMP_MARKER).write_text(_ownership("tmp", target=self.path.name))

    @staticmethod
    def _first_free(path: Path, start: int = 1) -> Path:
        """``path`` itself (``start = 1``) or the first free numbered sibling ``<name>-k``,
        ``k >= max(start, 2)``; a folder is free if absent or empty."""
        for k in range(start, 10000):
            cand = path if k == 1 else path.with_name(f"{path.name}-{k}")
            if not cand.exists() or (cand.is_dir() and not any(cand.iterdir())):
                return cand
        raise OutputError(f"output: no free numbered folder next to {path}")

    def _check_policy(self) -> None:
        p = self.path
        if len(os.fsencode(p.name)) > 200:
            raise OutputError(f"output: folder name of {len(p.name)} characters is too long "
                              "(at most 200)")
        _refuse_inside_runs(p)
        if p.is_symlink() and not p.exists():
            raise OutputError(f"output: {p} is a broken symbolic link")
        if not p.exists():
            return
        if not p.is_dir():
            raise OutputError(f"output: {p} exists and is not a directory; choose another "
                              "--out (nothing was changed)")
        if p.is_symlink():
            raise OutputError(f"output: {p} is a symbolic link; give the folder itself")
        try:
            content = [c.name for c in p.iterdir()]
        except OSError as exc:
            raise OutputError(f"output: cannot read {p} ({exc.strerror})") from None
        if not content:
            return
        previous_run_files(p)  # a run of this tool, every file of it intact
        if self.if_exists != "overwrite":
            raise OutputError(f"output: {p} holds a previous run; pass --overwrite to replace "
                              "it, or --set output.if_exists=new for a numbered folder")

    def _take_lock(self) -> bool:
        """Take the lock of :attr:`path`; False if a live process holds it and the policy is
        ``new`` (the caller tries the next number), :class:`OutputError` otherwise. A lock is
        taken over only when it is provably ours (:func:`_read_ours`) and its process is gone;
        a file or folder of that name we cannot prove we wrote is refused, never deleted."""
        lock = self.path.with_name(f".{self.path.name}.lock")
        for _ in range(2):
            try:
                fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                data = _read_ours(lock, "lock")
                if data is None:
                    raise OutputError(f"output: {lock} is not a lock this tool wrote (or is being "
                                      "written); remove it if no run is writing there, or "
                                      "choose another --out") from None
                pid = data["pid"]
                if pid != os.getpid() and _pid_alive(pid):
                    if self.if_exists == "new":
                        return False
                    raise OutputError(f"output: another run (pid {pid}) is writing {self.path}; "
                                      "wait for it or choose another --out") from None
                try:  # our own lock, of a process that is gone
                    lock.unlink()
                except FileNotFoundError:
                    pass
                continue
            except OSError as exc:
                if exc.errno == errno.ENAMETOOLONG:
                    raise OutputError(f"output: path too long: {self.path}") from None
                raise
            with os.fdopen(fd, "w") as fh:
                fh.write(lock_text())
            self._lock = lock
            return True
        raise OutputError(f"output: cannot take the lock {lock}")

    # ------------------------------------------------------------------ completion
    def commit(self) -> Path:
        """Move the complete result (every entry written into :attr:`tmp`) into place, with the
        marker listing them and their SHA-256; returns the output directory. SIGINT/SIGTERM are
        held until the move is complete; a previous run is replaced under a journal
        (:meth:`_replace_into`), so that even a kill leaves a state :func:`recover` settles."""
        assert self.tmp is not None, "prepare() first"
        ours = (MARKER, TMP_MARKER, JOURNAL, ASIDE)
        files = sorted(c.name for c in self.tmp.iterdir() if c.name not in ours)
        for name in files:
            if not (self.tmp / name).is_file():
                raise OutputError(f"output: {name} is not a file (the outputs are files)")
        digests = {name: sha256(self.tmp / name) for name in files}
        (self.tmp / MARKER).write_text(json.dumps({
            "tool": _TOOL, "version": __version__,
            "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "files": digests}, indent=1))
        for name in [*files, MARKER]:
            os.chmod(self.tmp / name, 0o644)
        p = self.path
        with _signals_held():
            if not p.exists():
                (self.tmp / TMP_MARKER).unlink()
                os.replace(self.tmp, p)
            else:
                self._replace_into(p, files)
                shutil.rmtree(self.tmp)
            self.committed = True
            self.tmp = None
            self._created = []
            self._release()
        return p

    def _replace_into(self, p: Path, files: list[str]) -> None:
        """Replace a previous run in ``p`` (checked again: the folder may have changed during
        the computation) by the files of :attr:`tmp`, with renames only: the journal first, then
        the old marker and files aside into :attr:`tmp`, the new files in, the new marker last.
        An error puts the previous run back (:func:`_settle`); a kill leaves the journal, which
        :func:`recover` settles the same way."""
        assert self.tmp is not None
        empty = not any(p.iterdir())
        old = {} if empty else previous_run_files(p)
        if not empty and self.if_exists != "overwrite":
            self.abort()
            raise OutputError(f"output: {p} changed during the run; the result was discarded")
        clash = [n for n in files if (p / n).exists() or (p / n).is_symlink()]
        clash = [n for n in clash if n not in old]
        if clash:
            self.abort()
            raise OutputError(f"output: {p} holds {clash[0]!r}, which nsm-continuation did not "
                              "write; the result was discarded (nothing was changed)")
        if (p / MARKER).is_file():
            old[MARKER] = sha256(p / MARKER)
        new = {name: sha256(self.tmp / name) for name in [*files, MARKER]}
        aside = self.tmp / ASIDE
        aside.mkdir()
        part = self.tmp / f"{JOURNAL}.part"
        part.write_text(json.dumps({"tool": _TOOL, "kind": "commit", "pid": os.getpid(),
                                    "uid": os.getuid(), "target": p.name, "old": old,
                                    "new": new}))
        os.replace(part, self.tmp / JOURNAL)
        try:
            for name in [MARKER, *[n for n in old if n != MARKER]]:
                if name in old:
                    os.replace(p / name, aside / name)
            for name in [*files, MARKER]:
                os.replace(self.tmp / name, p / name)
        except OSError:
            _settle(self.tmp, p, old, new)
            self.tmp = None
            raise

    def abort(self) -> None:
        """Remove the temporary directory, the lock and the folders this run created (the
        previous result stays intact: a commit cut half-way is rolled back first)."""
        if self.tmp is not None:
            journal = _read_journal(self.tmp)
            if journal is not None:
                _settle(self.tmp, self.tmp.parent / journal["target"], journal["old"],
                        journal["new"])
            else:
                shutil.rmtree(self.tmp, ignore_errors=True)
            self.tmp = None
        self._release()
        for d in reversed(self._created):
            try:
                d.rmdir()  # only if still empty
            except OSError:
                pass
        self._created = []

    def _release(self) -> None:
        if self._lock is not None:
            try:
                self._lock.unlink()
            except OSError:
                pass
            self._lock = None


def _refuse_inside_runs(path: Path) -> None:
    """Refuse an output location inside another run's temporary folder or inside a run folder
    (one holding :data:`MARKER`), or named like a temporary folder: that run's clean-up, or its
    next ``--overwrite``, would remove this run's result. Checked on the path as given and with
    symbolic links resolved."""
    seen = [Path(os.path.abspath(path))]
    try:
        seen.append(Path(os.path.realpath(path)))
    except (OSError, ValueError):
        pass
    for p in seen:
        if TMP_NAME.match(p.name):
            raise OutputError(f"output: {p} is named like the temporary folder of a run "
                              "(.<name>.tmp-*); choose another --out")
        for anc in p.parents:
            if TMP_NAME.match(anc.name):
                raise OutputError(f"output: {p} is inside {anc}, the temporary folder of "
                                  "another run; choose another --out")
            if (anc / MARKER).is_file():
                raise OutputError(f"output: {p} is inside {anc}, the folder of a previous run "
                                  "(its overwrite would remove this one); choose another --out")


def _read_journal(tmp: Path) -> dict | None:
    """The journal of a commit in the temporary folder ``tmp``, if there is one of ours."""
    data = _read_ours(tmp / JOURNAL, "commit")
    if data is None or not isinstance(data.get("old"), dict) \
            or not isinstance(data.get("new"), dict) or not isinstance(data.get("target"), str) \
            or Path(data["target"]).name != data["target"]:
        return None
    names = [*data["old"], *data["new"]]
    if any(not isinstance(n, str) or Path(n).name != n or n in ("", ".", "..") for n in names):
        return None
    return data


def _is_file_with(path: Path, digest: str) -> bool:
    return path.is_file() and not path.is_symlink() and sha256(path) == digest


def _settle(tmp: Path, p: Path, old: dict[str, str], new: dict[str, str]) -> str:
    """Settle a commit of ``tmp`` into ``p`` that was cut (an error, or a kill: then called by
    :func:`recover`); returns what was done. If the new marker is in place the new run is
    complete: the old files kept aside are dropped. Otherwise the previous run is put back: the
    new files already moved into ``p`` (each checked to be, byte for byte, ours) go back to
    ``tmp``, the old ones return from the aside folder, the old marker last. Renames only; then
    ``tmp`` is removed."""
    aside = tmp / ASIDE
    if MARKER in new and _is_file_with(p / MARKER, new[MARKER]):
        shutil.rmtree(tmp, ignore_errors=True)
        return f"finished the interrupted replacement of {p} (the new run is complete)"
    for name in [MARKER, *[n for n in new if n != MARKER]]:
        if name not in new or (tmp / name).exists() or (tmp / name).is_symlink():
            continue  # not moved in
        if name in old and not (aside / name).exists():
            continue  # the old file has not been moved aside: this is still the old one
        if _is_file_with(p / name, new[name]):
            os.replace(p / name, tmp / name)
    for name in [*[n for n in old if n != MARKER], MARKER]:
        if name in old and (aside / name).exists() and not (p / name).exists():
            os.replace(aside / name, p / name)
    shutil.rmtree(tmp, ignore_errors=True)
    return f"restored the previous run in {p} (a replacement of it was interrupted)"


def recover(parent: Path | str, target: str | None = None) -> list[str]:
    """Settle what killed runs left in the folder ``parent`` (only for the output folder named
    ``target`` when given): an interrupted replacement (its journal) is rolled back or finished
    (:func:`_settle`), the temporary folder of a run whose process is gone is removed, a lock of
    ours whose process is gone is removed. Only what is provably ours (:func:`_read_ours`: a
    regular file of the current user holding our JSON) and whose process is gone is touched;
    returns one line per thing done."""
    parent = Path(parent)
    done: list[str] = []
    try:
        entries = sorted(parent.iterdir())
    except OSError:
        return done
    for tmp in entries:
        m = TMP_NAME.match(tmp.name)
        if m is None or (target is not None and m.group(1) != target) or tmp.is_symlink() \
                or not tmp.is_dir():
            continue
        owner = _read_ours(tmp / TMP_MARKER, "tmp")
        if owner is None or owner["pid"] == os.getpid() or _pid_alive(owner["pid"]):
            continue
        journal = _read_journal(tmp)
        try:
            if journal is not None and journal["pid"] == owner["pid"]:
                done.append(_settle(tmp, parent / journal["target"], journal["old"],
                                    journal["new"]))
            else:
                shutil.rmtree(tmp)
                done.append(f"removed {tmp}, the temporary folder of a run that was killed")
        except OSError as exc:
            done.append(f"could not clean up {tmp} ({exc.strerror or exc})")
    for lock in entries:
        m = re.match(r"^\.(.+)\.lock$", lock.name)
        if m is None or (target is not None and m.group(1) != target):
            continue
        data = _read_ours(lock, "lock")
        if data is not None and data["pid"] != os.getpid() and not _pid_alive(data["pid"]):
            try:
                lock.unlink()
            except OSError:
                continue
            done.append(f"removed {lock}, the lock of a run that was killed")
    return done
