"""Atomic file output: every file this package writes goes through :func:`write_atomic`.

A reader never sees a half-written file, and an existing file is never replaced unless the
caller asked for it (``overwrite=True``, the CLIs' ``--force``). Outputs that belong together
(a fitted .tir and its report) go through :class:`OutputSet`: all of them or none.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_atomic(
    path: str | os.PathLike[str], data: bytes | str, *, overwrite: bool = False
) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder.

    Text is written as UTF-8 with ``\\n`` line ends. Permissions follow the umask (a temporary
    file is created 0600). Without ``overwrite`` the file is put in place with ``link()``, which
    fails if the target appeared meanwhile, so a file that is not ours is never clobbered.

    Raises
    ------
    FileExistsError
        if ``path`` exists and ``overwrite`` is False.
    """
    target = Path(path)
    if target.exists() and not overwrite:
        raise FileExistsError(f"{target}: exists; not overwriting it (use --force)")
    payload = data.encode("utf-8") if isinstance(data, str) else data
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(payload)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        if overwrite:
            os.replace(tmp, target)
        else:
            os.link(tmp, target)
            os.unlink(tmp)
    except FileExistsError:
        os.unlink(tmp)
        raise FileExistsError(f"{target}: exists; not overwriting it (use --force)") from None
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return target


def replace_path(new: Path, target: Path) -> None:
    """Move the finished ``new`` (file or folder) to ``target``, replacing what is there.

    A folder cannot be renamed over a non-empty folder: an existing one is moved aside first,
    put back if the move fails (never lost), and deleted once ``new`` is in place.
    """
    if not target.is_dir() or target.is_symlink():
        os.replace(new, target)
        return
    old = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-", dir=target.parent))
    os.rmdir(old)
    os.replace(target, old)
    try:
        os.replace(new, target)
    except BaseException:
        os.replace(old, target)
        raise
    shutil.rmtree(old, ignore_errors=True)


# --------------------------------------------------------------------------------------------
# Several outputs, whole or not at all
# --------------------------------------------------------------------------------------------

JOURNAL = "journal.json"  # in a staging folder: the renames decided; its presence commits
_OWNER = "owner"  # the pid of the run that stages


class OutputSet:
    """Several outputs (files or folders) that appear together or not at all.

    Everything is written into a hidden staging folder beside the first target,
    ``.NAME.partial`` (:meth:`path` gives each target's place in it), then :meth:`commit` writes a
    journal of the renames that put it in place and carries them out. A run interrupted before
    the journal leaves only the staging folder, which the next :meth:`recover` removes (roll
    back); one interrupted after it has decided, and the next :meth:`recover` finishes the renames
    (roll forward). The targets are renamed in their given order: ``fit`` lists OUT.tir before
    its report, so an interruption between the renames (system calls apart) leaves the .tir
    without its report, never a report without its .tir, until the next run completes it.

    A folder target that exists already receives its files one by one (other files in it are
    kept). Without ``overwrite`` nothing that exists is replaced. All targets must be on the
    file system of the first (a rename cannot cross file systems).

    Usage::

        outputs = OutputSet([out_tir, report_dir], overwrite=force)
        for note in outputs.recover(): print(note)
        with outputs:
            write_tir(tir, outputs.path(out_tir))
            write_report(..., outputs.path(report_dir))
            outputs.commit()
    """

    def __init__(self, targets: list[Path], *, overwrite: bool = False) -> None:
        if not targets:
            raise ValueError("OutputSet needs at least one target")
        self.targets = [Path(t) for t in targets]
        self.overwrite = overwrite
        first = self.targets[0]
        self.staging = first.parent / f".{first.name}.partial"
        self._committed = False

    def path(self, target: Path) -> Path:
        """Where to write ``target`` while staging."""
        return self.staging / "items" / str(self.targets.index(Path(target)))

    # -- recovery ------------------------------------------------------------------------
    def recover(self) -> list[str]:
        """Finish or remove what an interrupted run left; one line per thing done.

        Raises
        ------
        FileExistsError
            when the staging folder belongs to a run that is still going on.
        """
        if not self.staging.exists():
            return []
        pid = _owner(self.staging)
        if pid is not None and pid != os.getpid() and _alive(pid):
            raise FileExistsError(
                f"{self.staging}: another run (pid {pid}) is writing {self.targets[0]}; "
                "if none is, remove this folder"
            )
        journal = self.staging / JOURNAL
        if not journal.exists():
            shutil.rmtree(self.staging)
            return [f"removed the unfinished output of an interrupted run ({self.staging})"]
        moves, overwrite = _read_journal(journal)
        done = _apply(moves, overwrite)
        shutil.rmtree(self.staging)
        if not done:
            return []
        names = ", ".join(str(t) for t in done)
        return [f"finished the output of an interrupted run: {names} put in place"]

    # -- staging and commit --------------------------------------------------------------
    def __enter__(self) -> OutputSet:
        device = os.stat(self.staging.parent).st_dev
        for target in self.targets:
            if os.stat(target.parent).st_dev != device:
                raise OSError(f"{target}: not on the file system of {self.targets[0]}")
        self.staging.mkdir()  # fails if a run is staging already (recover() first)
        write_atomic(self.staging / _OWNER, str(os.getpid()))
        (self.staging / "items").mkdir()
        return self

    def __exit__(self, *exc: object) -> None:
        if not self._committed and self.staging.exists():
            shutil.rmtree(self.staging)  # nothing decided: nothing of this run stays

    def commit(self) -> list[Path]:
        """Put every staged output in place (the targets in their order); returns them.

        Raises
        ------
        FileExistsError
            naming a target that exists, without ``overwrite`` (nothing is moved then).
        FileNotFoundError
            for a target that was not written into the staging folder.
        """
        moves: list[tuple[Path, Path]] = []
        for target in self.targets:
            staged = self.path(target)
            if not staged.exists():
                raise FileNotFoundError(f"{target}: not written (nothing put in place)")
            moves += _plan(staged, target)
        if not self.overwrite:
            for _, target in moves:
                if target.exists() or target.is_symlink():
                    raise FileExistsError(f"{target}: exists; not overwriting it (use --force)")
        journal = {
            "moves": [[str(s.relative_to(self.staging)), str(t.absolute())] for s, t in moves],
            "overwrite": self.overwrite,
        }
        write_atomic(self.staging / JOURNAL, json.dumps(journal))
        self._committed = True  # decided: from here a failure is finished by the next run
        _apply([(s, t.absolute()) for s, t in moves], self.overwrite)
        shutil.rmtree(self.staging)
        return self.targets


def _owner(staging: Path) -> int | None:
    try:
        return int((staging / _OWNER).read_text())
    except (OSError, ValueError):
        return None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # another user's process
    return True


def _plan(staged: Path, target: Path) -> list[tuple[Path, Path]]:
    """The renames that put ``staged`` at ``target``: a folder into an existing folder file
    by file, anything else whole."""
    if staged.is_dir() and target.is_dir() and not target.is_symlink():
        return [m for child in sorted(staged.iterdir()) for m in _plan(child, target / child.name)]
    return [(staged, target)]


def _read_journal(journal: Path) -> tuple[list[tuple[Path, Path]], bool]:
    data = json.loads(journal.read_text())
    moves = [(journal.parent / s, Path(t)) for s, t in data["moves"]]
    return moves, bool(data["overwrite"])


def _apply(moves: list[tuple[Path, Path]], overwrite: bool) -> list[Path]:
    """Carry out the renames not done yet (their source is gone when done); returns the
    targets it put in place."""
    done = []
    for staged, target in moves:
        if not (staged.exists() or staged.is_symlink()):
            continue
        if overwrite or staged.is_dir():
            os.replace(staged, target)  # a folder only over nothing or an empty folder
        else:
            _link_into_place(staged, target)
        done.append(target)
    return done


def _link_into_place(staged: Path, target: Path) -> None:
    """Rename a file without replacing anything: link (fails if the target exists), unlink."""
    try:
        os.link(staged, target)
    except FileExistsError:
        if not os.path.samefile(staged, target):  # linked before an interruption: ours
            raise FileExistsError(f"{target}: exists; not overwriting it (use --force)") from None
    os.unlink(staged)
