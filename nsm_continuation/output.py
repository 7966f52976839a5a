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
    marker are removed, anything the user added to the folder stays;
  - or, with ``output.if_exists: new``, left alone: the run goes to the first free numbered
    sibling ``<name>-2``, ``<name>-3``, ...;
  - refused in every other case (a regular file, a directory with files this tool did not
    write), before anything is computed.
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
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from . import __version__
from .cases import CaseError, short_text

#: marker file of a run directory: JSON with the tool, its version, the time and the files written
MARKER = ".nsm-continuation-run.json"
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


def read_marker(directory: Path) -> dict | None:
    """The marker of a run directory, or None if ``directory`` is not a run of this tool."""
    try:
        data = json.loads((directory / MARKER).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("tool") != "nsm-continuation" \
            or not isinstance(data.get("files"), list):
        return None
    return data


@dataclass
class OutputTarget:
    """One run's output directory, from the preflight check to the final move into place."""

    path: Path
    if_exists: IfExists = "error"
    tmp: Path | None = field(default=None, init=False)
    _lock: Path | None = field(default=None, init=False)

    # ------------------------------------------------------------------ preflight
    def prepare(self) -> None:
        """Check the policy and the location, take the lock, create the temporary directory.

        Raises :class:`OutputError` naming the path; on error nothing is left behind.
        """
        try:
            self._prepare()
        except (OSError, ValueError) as exc:  # a name too long, a NUL byte, an odd mount...
            if isinstance(exc, OutputError):
                raise
            self.abort()
            why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
            raise OutputError(f"output: cannot use {short_text(str(self.path))} ({why})") from None

    def _prepare(self) -> None:
        self.path = Path(os.path.abspath(self.path))
        if self.if_exists == "new":
            self.path = self._first_free(self.path)
        self._check_policy()
        parent = self.path.parent
        try:
            parent.mkdir(parents=True, exist_ok=True, mode=0o755)
        except FileExistsError:
            raise OutputError(f"output: {parent} exists and is not a directory") from None
        except OSError as exc:
            raise OutputError(f"output: cannot create {parent} ({exc.strerror})") from None
        if not parent.is_dir():
            raise OutputError(f"output: {parent} is not a directory")
        try:
            free = shutil.disk_usage(parent).free
        except OSError:
            free = MIN_FREE_BYTES
        if free < MIN_FREE_BYTES:
            raise OutputError(f"output: only {free / 2**20:.1f} MiB free in {parent} (a run "
                              f"needs at least {MIN_FREE_BYTES // 2**20} MiB)")
        self._take_lock()
        try:
            self.tmp = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.tmp-", dir=parent))
            os.chmod(self.tmp, 0o755)
            probe = self.tmp / ".write-test"
            probe.write_bytes(b"x")
            probe.unlink()
        except OSError as exc:
            self.abort()
            raise OutputError(f"output: cannot write in {parent} ({exc.strerror or exc})"
                              ) from None

    @staticmethod
    def _first_free(path: Path) -> Path:
        if not path.exists() or (path.is_dir() and not any(path.iterdir())):
            return path
        for k in range(2, 10000):
            cand = path.with_name(f"{path.name}-{k}")
            if not cand.exists():
                return cand
        raise OutputError(f"output: no free numbered folder next to {path}")

    def _check_policy(self) -> None:
        p = self.path
        if len(p.name.encode()) > 200:
            raise OutputError(f"output: folder name of {len(p.name)} characters is too long "
                              "(at most 200)")
        if p.is_symlink() and not p.exists():
            raise OutputError(f"output: {p} is a broken symbolic link")
        if not p.exists():
            return
        if not p.is_dir():
            raise OutputError(f"output: {p} exists and is not a directory; choose another "
                              "--out (nothing was changed)")
        try:
            content = [c.name for c in p.iterdir()]
        except OSError as exc:
            raise OutputError(f"output: cannot read {p} ({exc.strerror})") from None
        if not content:
            return
        marker = read_marker(p)
        if marker is None:
            raise OutputError(f"output: {p} already holds files that nsm-continuation did not "
                              "write; choose another --out (nothing was changed)")
        if self.if_exists != "overwrite":
            raise OutputError(f"output: {p} holds a previous run; pass --overwrite to replace "
                              "it, or --set output.if_exists=new for a numbered folder")

    def _take_lock(self) -> None:
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
                    raise OutputError(f"output: another run (pid {pid}) is writing {self.path}; "
                                      "wait for it or choose another --out") from None
                try:  # stale lock of a process that is gone
                    lock.unlink()
                except FileNotFoundError:
                    pass
                except OSError as exc:
                    raise OutputError(f"output: cannot remove the stale lock {lock} "
                                      f"({exc.strerror})") from None
                continue
            except OSError as exc:
                if exc.errno == errno.ENAMETOOLONG:
                    raise OutputError(f"output: path too long: {self.path}") from None
                raise OutputError(f"output: cannot write in {self.path.parent} "
                                  f"({exc.strerror})") from None
            with os.fdopen(fd, "w") as fh:
                fh.write(str(os.getpid()))
            self._lock = lock
            return
        raise OutputError(f"output: cannot take the lock {lock}")

    # ------------------------------------------------------------------ completion
    def commit(self) -> Path:
        """Move the complete result (every entry written into :attr:`tmp`) into place, with the
        marker listing them; returns the output directory."""
        assert self.tmp is not None, "prepare() first"
        files = sorted(c.name for c in self.tmp.iterdir() if c.name != MARKER)
        (self.tmp / MARKER).write_text(json.dumps({
            "tool": "nsm-continuation", "version": __version__,
            "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "files": files}, indent=1))
        for name in [*files, MARKER]:
            os.chmod(self.tmp / name, 0o755 if (self.tmp / name).is_dir() else 0o644)
        p = self.path
        if not p.exists():
            os.replace(self.tmp, p)
        else:
            # an empty directory, or a previous run the user asked to replace (checked again:
            # the folder may have changed during the computation)
            old = read_marker(p)
            if any(p.iterdir()) and (old is None or self.if_exists != "overwrite"):
                self.abort()
                raise OutputError(f"output: {p} changed during the run and now holds files "
                                  "nsm-continuation did not write; the result was discarded")
            ours = {str(n) for n in (old or {}).get("files", [])}
            clash = [n for n in files if (p / n).exists() and n not in ours]
            if clash:
                self.abort()
                raise OutputError(f"output: {p} holds {clash[0]!r}, which nsm-continuation did "
                                  "not write; the result was discarded (nothing was changed)")
            for name in [*(old or {}).get("files", []), MARKER]:
                target = p / str(name)
                if Path(str(name)).name != name or not target.exists():
                    continue  # only plain names this tool listed, never a path
                if target.is_dir() and not target.is_symlink():
                    shutil.rmtree(target)
                else:
                    target.unlink()
            for name in [*files, MARKER]:
                os.replace(self.tmp / name, p / name)
            shutil.rmtree(self.tmp, ignore_errors=True)
        self.tmp = None
        self._release()
        return p

    def abort(self) -> None:
        """Remove the temporary directory and the lock (the previous result stays intact)."""
        if self.tmp is not None:
            shutil.rmtree(self.tmp, ignore_errors=True)
            self.tmp = None
        self._release()

    def _release(self) -> None:
        if self._lock is not None:
            try:
                self._lock.unlink()
            except OSError:
                pass
            self._lock = None
