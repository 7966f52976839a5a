"""Where a run writes, and the promise that it never loses a user's data.

The output policy (README, "Output folders"):

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
  result is either the previous one or the new one, never a mixture.
* Two runs cannot write the same target at once: a lock file ``.<name>.lock`` (created with
  ``O_EXCL``, holding the owner's PID) is taken before computing; a stale lock (its process is
  gone) is taken over.
* Directories get mode 0755 and files 0644 (subject to the user's umask), like any other tool.

:meth:`OutputTarget.prepare` checks all of this, and that the location is creatable and writable
with free space, **before** the computation; failures are :class:`OutputError` (exit status 2)
with one line naming the path.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
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
        probe = self.tmp / ".write-test"
        probe.write_bytes(b"x")
        probe.unlink()

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
        ``new`` (the caller tries the next number), :class:`OutputError` otherwise."""
        lock = self.path.with_name(f".{self.path.name}.lock")
        for _ in range(2):
            try:
                fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                try:
                    pid = int(lock.read_text().strip() or 0)
                except (OSError, ValueError):
                    pid = 0
                if pid and pid != os.getpid() and _pid_alive(pid):
                    if self.if_exists == "new":
                        return False
                    raise OutputError(f"output: another run (pid {pid}) is writing {self.path}; "
                                      "wait for it or choose another --out") from None
                try:  # stale lock of a process that is gone
                    lock.unlink()
                except FileNotFoundError:
                    pass
                continue
            except OSError as exc:
                if exc.errno == errno.ENAMETOOLONG:
                    raise OutputError(f"output: path too long: {self.path}") from None
                raise
            with os.fdopen(fd, "w") as fh:
                fh.write(str(os.getpid()))
            self._lock = lock
            return True
        raise OutputError(f"output: cannot take the lock {lock}")

    # ------------------------------------------------------------------ completion
    def commit(self) -> Path:
        """Move the complete result (every entry written into :attr:`tmp`) into place, with the
        marker listing them and their SHA-256; returns the output directory. SIGINT/SIGTERM are
        held until the move is complete."""
        assert self.tmp is not None, "prepare() first"
        files = sorted(c.name for c in self.tmp.iterdir() if c.name != MARKER)
        for name in files:
            if not (self.tmp / name).is_file():
                raise OutputError(f"output: {name} is not a file (the outputs are files)")
        digests = {name: sha256(self.tmp / name) for name in files}
        (self.tmp / MARKER).write_text(json.dumps({
            "tool": "nsm-continuation", "version": __version__,
            "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "files": digests}, indent=1))
        for name in [*files, MARKER]:
            os.chmod(self.tmp / name, 0o644)
        p = self.path
        with _signals_held():
            if not p.exists():
                os.replace(self.tmp, p)
            else:
                self._replace_into(p, files)
                shutil.rmtree(self.tmp, ignore_errors=True)
            self.committed = True
            self.tmp = None
            self._created = []
            self._release()
        return p

    def _replace_into(self, p: Path, files: list[str]) -> None:
        """Replace a previous run in ``p`` (checked again: the folder may have changed during
        the computation) by the files of :attr:`tmp`; the old files are kept aside until the new
        ones are in place."""
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
        aside = self.tmp / ".previous"
        aside.mkdir()
        moved: list[str] = []
        try:
            for name in [*old, MARKER]:
                if (p / name).exists():
                    os.replace(p / name, aside / name)
                    moved.append(name)
            for name in [*files, MARKER]:
                os.replace(self.tmp / name, p / name)
        except OSError:
            for name in moved:  # put the previous run back
                if not (p / name).exists():
                    os.replace(aside / name, p / name)
            raise

    def abort(self) -> None:
        """Remove the temporary directory, the lock and the folders this run created (the
        previous result stays intact)."""
        if self.tmp is not None:
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
