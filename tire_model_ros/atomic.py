"""Atomic file output: every file this package writes goes through :func:`write_atomic`.

A reader never sees a half-written file, and an existing file is never replaced unless the
caller asked for it (``overwrite=True``, the CLIs' ``--force``).
"""

from __future__ import annotations

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
