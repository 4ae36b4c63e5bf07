"""File helpers: atomic writes and content hashes.

Every file geoproc writes goes to a temporary file beside its destination and
is renamed only when complete (:func:`write_files_atomic`), so a failed run
never leaves a partial output behind.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import os
import secrets
import stat
from collections.abc import Callable

from geoproc.errors import InputError


def folder_of(path: str | os.PathLike) -> str:
    """The folder a file ``path`` is written in, as the file system resolves it:
    the path's text up to its last separator (``.`` when there is none), with
    any ``..`` left for the system to resolve after a symbolic link, where
    ``os.path.abspath`` would drop the link's folder and name another one."""
    return os.path.dirname(os.fspath(path)) or os.curdir


def _temp_name_beside(path: str) -> str:
    """A fresh name for a temporary file in the folder of ``path`` (not created):
    a dot, at most the first 200 bytes of the target's name (so that it stays
    within the 255-byte name limit whatever the target's length), 16 random hex
    digits and ``.tmp``."""
    base = os.fsencode(os.path.basename(path))[:200]
    folder = os.fsencode(folder_of(path))
    return os.fsdecode(os.path.join(folder, b"." + base + b"." + secrets.token_hex(8).encode() + b".tmp"))


def _create_beside(path: str, names: list[str]) -> int:
    """Create a temporary file beside ``path``; its name is appended to
    ``names`` before the file exists, so that an interruption between the two
    cannot leave a file no one removes (``tempfile.mkstemp`` had such a gap).
    Returns its descriptor, open for writing."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)
    while True:
        name = _temp_name_beside(path)
        names.append(name)
        try:
            return os.open(name, flags, 0o600)
        except FileExistsError:  # that name is taken (not ours): another
            names.pop()
        except OSError:  # not made: the error is the destination's, not this name's
            names.pop()
            raise


def _keep_old(path: str, names: list[str]) -> str | None:
    """A second name (a hard link beside it, appended to ``names`` before it is
    made) for the regular file at ``path``, so that it can be put back if a
    later rename fails; None when there is no such file or the file system
    cannot link it."""
    if not os.path.isfile(path):
        return None
    name = _temp_name_beside(path)
    names.append(name)
    try:
        os.link(path, name)
    except OSError:
        names.pop()
        return None
    return name


def _rename_all(staged: list[tuple[str, str, str]], names: list[str]) -> None:
    """Rename every (temporary, destination, name given) triple; if one fails
    (or a signal arrives) the destinations get their old files back, or are
    removed when there were none, so the outputs stay all old or all new (a
    file system that cannot hard-link keeps the new file where an old one
    was). An OSError names the destination as it was given. The old files'
    second names are appended to ``names`` too, so that the caller removes
    them if an interruption cuts this short."""
    done: list[tuple[str, bool, str | None]] = []  # (destination, existed, its old file's second name)
    try:
        for tmp, path, given in staged:
            existed = os.path.lexists(path)
            old = _keep_old(path, names) if existed else None
            done.append((path, existed, old))
            try:
                os.replace(tmp, path)
            except OSError as exc:
                raise OSError(exc.errno, exc.strerror or str(exc), given) from exc
    except BaseException:
        for path, existed, old in reversed(done):  # the last may have failed: restoring it changes nothing
            with contextlib.suppress(OSError):
                if old is not None:
                    os.replace(old, path)
                elif not existed:
                    os.unlink(path)
        raise  # the caller removes the second names left (a failed restore, a rename onto the same file)
    _discard([old for _, _, old in done if old is not None])


def _discard(temps: list[str]) -> None:
    """Remove these files where they exist; a removal that fails is left (it
    must not replace the error being reported)."""
    for tmp in temps:
        with contextlib.suppress(OSError):
            os.unlink(tmp)


def _umask_mode() -> int:
    """0o666 less the process umask: the mode ``open`` would give a new file."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def write_files_atomic(files: list[tuple[str | os.PathLike, bytes]],
                       before_rename: Callable[[], None] | None = None) -> None:
    """Write several files all or none: each goes to a temporary file beside its
    destination first, and only when every one is written are they renamed.

    A destination that is a folder, or a write that fails (permissions, disk
    full), raises OSError naming that destination before any destination
    changes; the temporary files are removed. A rename that fails (a
    destination bind-mounted or immutable) puts back the files the renames
    before it replaced (:func:`_rename_all`). New files get the usual mode
    (0o666 less the umask). A symbolic link is written through (its target is
    replaced, the link kept); a destination that exists and is not a regular
    file (a device such as /dev/null, a FIFO) is written to directly, once the
    others are staged.

    Parameters
    ----------
    files : list of (path, bytes)
    before_rename : callable, optional
        Called once everything is staged, before the renames (to write standard
        output); an OSError it raises discards the staged files too.
    """
    staged: list[tuple[str, str, str]] = []  # (temporary, destination, name given)
    temps: list[str] = []  # every temporary name, recorded before its file is made
    direct: list[tuple[str, bytes]] = []
    mode = _umask_mode()
    path = ""
    try:
        for path, data in files:
            path = os.fspath(path)
            real = os.path.realpath(path)
            kind = file_kind(path)  # through links, /dev/stdout's to a pipe too (realpath names no file there)
            if kind == "folder":
                raise IsADirectoryError(errno.EISDIR, "is a folder", path)
            if kind == "other":
                direct.append((path, data))
                continue
            fd = _create_beside(real, temps)
            tmp = temps[-1]
            staged.append((tmp, real, path))
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
            os.chmod(tmp, mode)
        for path, data in direct:
            with open(path, "wb") as fh:
                fh.write(data)
        path = "-"
        if before_rename is not None:
            before_rename()
        path = ""  # _rename_all names the destination it could not rename
        _rename_all(staged, temps)
    except BaseException as exc:
        _discard(temps)
        if isinstance(exc, OSError):  # name the destination, not the temporary file
            raise OSError(exc.errno, exc.strerror or str(exc), path or exc.filename) from exc
        raise


def file_kind(path: str) -> str:
    """``"missing"``, ``"folder"``, ``"file"`` (regular) or ``"other"`` (a device,
    a FIFO, a pipe or socket behind /dev/stdout), following symbolic links."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return "missing"
    return "folder" if stat.S_ISDIR(mode) else "file" if stat.S_ISREG(mode) else "other"


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`write_files_atomic`)."""
    write_files_atomic([(path, data)])


def file_extension(path: str | os.PathLike) -> str:
    """The extension of ``path``, lower case and without its dot (``""`` when
    there is none; a file named ``ply`` has none)."""
    return os.path.splitext(os.fspath(path))[1].lower().lstrip(".")


def require_input_file(path: str, what: str = "file") -> None:
    """Raise InputError naming ``path`` when it does not exist or is a folder
    (``what`` names the kind of file expected, e.g. ``"mesh file"``)."""
    if os.path.isdir(path):
        raise InputError(path, f"is a directory, not a {what}")
    if not os.path.exists(path):
        raise InputError(path, "no such file")


def read_input_bytes(path: str, what: str = "file") -> bytes:
    """The content of the input file ``path``; InputError naming it when it is
    missing, a folder or unreadable (permissions, I/O errors)."""
    require_input_file(path, what)
    try:
        with open(path, "rb") as fh:
            return fh.read()
    except OSError as exc:
        raise InputError(path, f"cannot read: {exc.strerror or exc}") from None


def sha256_bytes(data: bytes) -> str:
    """Hex SHA-256 of ``data``."""
    return hashlib.sha256(data).hexdigest()


def sha256_file(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's content (a folder: of its sorted files' hashes)."""
    path = os.fspath(path)
    if os.path.isdir(path):
        h = hashlib.sha256()
        for name in sorted(os.listdir(path)):
            full = os.path.join(path, name)
            if os.path.isfile(full):
                h.update(os.fsencode(name) + b"\0" + sha256_file(full).encode())
        return h.hexdigest()
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()
