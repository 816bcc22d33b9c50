"""Write outputs to a temporary file in the destination folder, then rename.

Nothing half-written is ever left at the destination: on error the temporary file is removed.
Folders of outputs are built the same way (:func:`atomic_dir`).
"""

from __future__ import annotations

import contextlib
import errno
import glob
import json
import os
import re
import shutil
import stat
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import IO

from artmotion._native import signals_held
from artmotion.errors import InputError
from artmotion.io.files import as_path


def _not_regular(path: Path) -> InputError | None:
    """An error when ``path`` exists and is not a regular file (a device, a pipe, a socket): the
    rename of an atomic write would replace it (as root, even ``/dev/null``)."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return None  # nothing there (or a dangling link, which the rename replaces)
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    return InputError("not a regular file (a device, pipe or socket): give the name of a file to write", path=path)


#: the names the command line gave with a slash at the end (``--model newdir/``): a command's
#: :class:`Path` option has lost the slash before an output is written (set by ``artmotion.cli``)
SLASHED: set[str] = set()


def _file_name(path: str | os.PathLike) -> Path:
    """``path`` as a :class:`Path`, refused when it ends with a slash, or was given so on the
    command line (:data:`SLASHED`): ``--model newdir/`` wrote a file called ``newdir``, and the
    slash says a folder was meant."""
    as_path(path, "an output")      # (checked, not converted: a Path drops the trailing slash)
    raw = os.fsdecode(path)
    if raw.endswith(os.sep) or (os.altsep and raw.endswith(os.altsep)) or raw in SLASHED:
        raise InputError("ends with a slash, as a folder's name: give the name of a file to write", path=raw)
    return Path(raw)


def _through_link(path: Path) -> Path:
    """Where an output named by a link is written: the file the link names (the rename of an
    atomic write put a plain file in place of the link: ``--out /dev/stdout`` with stdout redirected
    replaced the system's /dev/stdout), which is kept a link. A link into /dev or /proc (a stream
    of the process, a device) is refused: its target is no file to replace."""
    if not path.is_symlink():
        return path
    target = Path(os.path.realpath(path))
    named = os.readlink(path)
    try:
        os.stat(path)
    except OSError as exc:      # (a link to no file is written through: its target is made ...
        if exc.errno == errno.ELOOP:
            raise InputError("is a link that loops (to itself, through other links): give the name of a file to "
                             "write", path=path) from None
        if not target.parent.is_dir():  # ... in a folder that exists: none is made where a link points
            raise InputError(f"is a link to {named}, in a folder that does not exist: give the name of a file to "
                             "write", path=path) from None
    if (target.parts[:2] == ("/", "proc") or named.startswith(("/proc/", "/dev/fd/"))
            or named in ("/dev/stdin", "/dev/stdout", "/dev/stderr")):
        raise InputError("is a link to a stream of the process (/dev/stdout and the like): give the name of "
                         "a file to write", path=path)
    return target   # (a device there is refused as not a regular file)


def _same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """``a`` and ``b`` name the same file (the same inode when both exist, else the same absolute path)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.abspath(a) == os.path.abspath(b)


def _prepare(path: str | os.PathLike, made: list[Path], is_folder: bool = False) -> Path:
    """``path`` as a :class:`Path` whose folder exists; the folders created for it are appended to
    ``made`` (outermost first), for :func:`_discard` to remove if the write fails. ``is_folder``: the
    output is a folder (:func:`atomic_dir`), whose name may end with a slash."""
    path = _through_link(as_path(path, "an output folder") if is_folder else _file_name(path))
    error = _not_regular(path)
    if error is not None:
        raise error
    missing = []
    folder = path.parent
    while not os.path.lexists(folder) and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    try:
        for folder in reversed(missing):
            made.append(folder)             # (before it exists: see _fresh)
            try:
                os.mkdir(folder)
            except FileExistsError:
                made.pop()                  # made at the same moment by another process (a batch's
                if not folder.is_dir():     # workers writing into one new --out): not ours to remove
                    raise
    except OSError as exc:
        raise InputError(f"cannot create output folder: {exc.strerror}", path=path.parent) from exc
    return path


def _ours(exc: OSError, made: list[Path]) -> bool:
    """Whether ``exc`` concerns the output being written (a file in one of the temporary names
    ``made``, or none named) rather than another file (an input the work reads)."""
    if not exc.filename:
        return True
    name = os.fspath(exc.filename)
    return any(name == os.fspath(p) or name.startswith(os.fspath(p) + os.sep) for p in made)


def _within(path: str | os.PathLike, folder: str | os.PathLike) -> bool:
    """``path`` is ``folder`` or lies somewhere inside it (links resolved)."""
    inner, outer = Path(os.path.realpath(path)), Path(os.path.realpath(folder))
    return inner == outer or outer in inner.parents


def check_apart(path: str | os.PathLike | None, inputs: Iterable[str | os.PathLike | None] = ()) -> None:
    """An :class:`InputError` when the output ``path`` (a file or a folder) lies in a folder among
    the command's ``inputs`` (a folder of frames or crops): it would replace one of them or become
    one more, read the next time."""
    if path is None:
        return
    for q in inputs:
        if q is not None and os.path.isdir(q) and _within(path, q):
            raise InputError(f"is inside the input folder {q}: write the output elsewhere", path=path)


def check_writable(*paths: str | os.PathLike | None, inputs: Iterable[str | os.PathLike | None] = ()) -> None:
    """Before long work: an :class:`InputError` naming the first output ``path`` (``None``s are
    skipped) that cannot be written — an existing folder where a file goes, a device or pipe, a
    parent that is a file or not writable, the same file as another output or as one of the
    command's ``inputs`` (its rename would destroy the input), a file inside an input folder
    (:func:`check_apart`) — without creating anything."""
    given = [_file_name(p) for p in paths if p is not None]
    sources = [q for q in inputs if q is not None]
    for k, path in enumerate(given):
        path = _through_link(path)
        check_apart(path, sources)
        if path.is_dir():
            raise InputError("is a folder, not a file", path=path)
        error = _not_regular(path)
        if error is not None:
            raise error
        if any(_same_file(path, other) for other in given[:k]):
            raise InputError("given for two outputs: one would replace the other", path=path)
        if any(os.path.isfile(q) and _same_file(path, q) for q in sources):
            raise InputError("is also an input: writing the output would destroy it", path=path)
        check_can_create_in(path.parent)


def _after(name: str, tmp: Path, path: Path) -> str | None:
    """The file ``name`` with the temporary ``tmp`` it lies in (or is) named ``path`` instead;
    ``None`` when it is not in ``tmp`` (a message never shows a temporary name)."""
    return str(path) + name[len(str(tmp)):] if name.startswith(str(tmp)) else None


def _renamed(exc: InputError, tmp: Path, path: Path) -> InputError:
    """``exc`` naming ``path`` where it names the temporary ``tmp``."""
    where = None if exc.path is None else _after(exc.path, tmp, path)
    return exc if where is None else InputError(exc.reason, path=where, line=exc.line)


#: the longest file name (bytes) of common file systems (ext4, XFS, APFS, NTFS in UTF-16 units)
NAME_MAX = 255


def _fitting(prefix: str, suffix: str, reserve: int = 0) -> tuple[str, str]:
    """``prefix`` cut (at a character) so that ``prefix + 8 characters + suffix`` fits in
    :data:`NAME_MAX` bytes (less ``reserve``, for names a writer derives from it, such as SQLite's
    ``-journal``): a 246-character video name made the temporary name of its run folder too long
    ("File name too long") although the folder's own name fitted. A ``suffix`` over 32 bytes is no
    file type's extension (``a.bbb…``): it becomes ``.tmp``."""
    if len(os.fsencode(suffix)) > 32:
        suffix = ".tmp"
    room = NAME_MAX - 8 - len(os.fsencode(suffix)) - reserve
    while prefix and len(os.fsencode(prefix)) > room:
        prefix = prefix[:-1]
    return prefix, suffix


def _fresh(parent: Path, prefix: str, suffix: str, folder: bool, made: list[Path], reserve: int = 0) -> Path:
    """Create a new, empty file (or ``folder``) of a random name ``prefix + 8 characters + suffix``
    in ``parent``, its permissions those of any new file (the umask's; ``mkstemp``'s 0600 would make
    outputs private to their writer). The name is put in ``made`` *before* it is created, so that
    a caller's clean-up removes it even when a signal interrupts right after the creation (the
    caller's ``try`` must hold this call); a name that turns out to be taken is removed from
    ``made`` before the next one is tried."""
    prefix, suffix = _fitting(prefix, suffix, reserve)
    for _ in range(1000):
        name = parent / f"{prefix}{os.urandom(4).hex()}{suffix}"
        made[:] = [name]
        try:
            if folder:
                os.mkdir(name, 0o777)
            else:
                os.close(os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            return name
        except FileExistsError:
            made.clear()
    raise FileExistsError(f"no free temporary name in {parent}")


def _discard(made: list[Path], folders: list[Path] | None = None) -> None:
    """Remove what :func:`_fresh` created (a file, or a folder and all in it), if it is there, then
    the ``folders`` :func:`_prepare` created, innermost first, if they are empty."""
    for name in made:
        if name.is_dir() and not name.is_symlink():
            shutil.rmtree(name, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                name.unlink()
    for folder in reversed(folders or []):
        with contextlib.suppress(OSError):
            folder.rmdir()


@contextlib.contextmanager
def _undone_on_failure(path: Path, made: list[Path], folders: list[Path]) -> Iterator[None]:
    """The block that writes ``path`` through the temporary names ``made`` (:func:`_fresh`), in the
    ``folders`` :func:`_prepare` created: if it fails or is interrupted, they are removed and an
    error is named after ``path``, never a temporary name. An OSError of the output (a full disk,
    a lost permission) becomes an :class:`InputError` ("cannot write"); one of another file (an
    input the block reads) passes as it is."""
    try:
        yield
    except InputError as exc:
        _discard(made, folders)
        renamed = _renamed(exc, made[0], path) if made else exc
        if renamed is exc:
            raise
        raise renamed from None
    except OSError as exc:
        _discard(made, folders)
        if not _ours(exc, [*made, path]):
            raise
        where = (_after(str(exc.filename), made[0], path) if exc.filename and made else None) or path
        raise InputError(f"cannot write: {exc.strerror or exc}", path=where) from exc
    except BaseException:
        _discard(made, folders)
        raise


class NameTaken(InputError):
    """:func:`atomic_path` with ``replace=False``: another process made the file meanwhile."""


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None, replace: bool = True,
                reserve: int = 0) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` if the block succeeds.

    Use for writers that want a file name (OpenCV's VideoWriter, matplotlib's savefig, SQLite).
    ``suffix`` defaults to the destination's suffix so that format detection by extension works.
    A failure or an interruption at any point, the temporary name's creation included, leaves
    nothing behind. ``replace=False``: ``path`` is claimed only if nothing is there by then (another
    process may have made it meanwhile), else :class:`NameTaken` and nothing is written.
    ``reserve``: bytes the temporary name leaves free for names the writer derives from it.
    """
    folders: list[Path] = []
    path = _prepare(path, folders)
    suffix = path.suffix if suffix is None else suffix
    made: list[Path] = []
    with _undone_on_failure(path, made, folders):
        tmp_path = _fresh(path.parent, f".{path.name}.", ".tmp" + suffix, False, made, reserve)
        yield tmp_path
        if replace:
            os.replace(tmp_path, path)
            return
        try:
            _claim(tmp_path, path)
        except FileExistsError:
            raise NameTaken("exists: another process made it meanwhile; nothing was replaced", path=path) from None


def _write_mode(mode) -> bool:
    """``mode`` is one of :func:`open`'s modes that write a fresh file: one ``w``, at most one of
    ``b``/``t`` and one ``+``, in any order."""
    return (isinstance(mode, str) and mode.count("w") == 1 and set(mode) <= set("wbt+")
            and len(set(mode)) == len(mode) and not {"b", "t"} <= set(mode))


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "w", encoding: str | None = "utf-8") -> Iterator[IO]:
    """Open a temporary file for writing; it replaces ``path`` only when the block succeeds.

    ``mode`` is a write mode (``"w"``, ``"wt"``, ``"wb"``, with ``+`` to read back what was
    written): the file is always written anew, so ``"a"`` (which would lose the contents it means
    to add to), ``"r"`` (which would empty the file) and ``"x"`` are refused with an
    :class:`InputError` before anything is touched."""
    if not _write_mode(mode):
        raise InputError(f"atomic_write: mode must be a write mode ('w', 'wt' or 'wb', with '+' to read back), "
                         f"got {mode!r}: the file is always written anew (an atomic write cannot append to it, "
                         "read it or refuse an existing one)")
    if "b" in mode:
        encoding = None
    with atomic_path(path) as tmp:
        try:
            with open(tmp, mode, encoding=encoding) as fh:
                yield fh
        except OSError as exc:
            raise InputError(f"cannot write: {exc.strerror}", path=path) from exc


def _plan_dir(path: str | os.PathLike, replace: Callable[[Path], bool] | None,
              outputs: Iterable[str]) -> tuple[Path, bool, bool]:
    """How :func:`atomic_dir` will write the output folder ``path``: the folder (a link to a folder
    followed: the outputs go where it points), whether earlier outputs of the command's own are
    swapped for the new ones, and whether the folder is the user's (``foreign``: an existing folder,
    empty or of other files, into which the ``outputs`` are moved, none over an existing name; an
    empty one is not replaced: it may be a mount point, or have the owner and mode its user gave
    it). An :class:`InputError` when it cannot be done."""
    path = as_path(path, "an output folder")
    if path.is_symlink():
        if not path.is_dir():
            raise InputError("is a link to no folder: give a folder or a new name", path=path)
        path = Path(os.path.realpath(path))
    if path.exists() and not path.is_dir():
        raise InputError("exists and is not a folder", path=path)
    try:
        empty = path.is_dir() and not any(path.iterdir())
    except OSError as exc:
        raise InputError(f"cannot read the folder: {exc.strerror}", path=path) from None
    swap = path.is_dir() and not empty and replace is not None and replace(path)
    foreign = path.is_dir() and not swap
    if foreign:
        _check_free(path, outputs)
    return path, bool(swap), foreign


def check_out_dir(path: str | os.PathLike, replace: Callable[[Path], bool] | None = None,
                  outputs: Iterable[str] = ()) -> None:
    """Before long work: an :class:`InputError` when :func:`atomic_dir` (same arguments) could not
    write the output folder ``path`` — a file there, a link to nothing, an output name that exists
    in a folder of the user's files, a folder that cannot be written — without creating anything."""
    path, swap, foreign = _plan_dir(path, replace, outputs)
    check_can_create_in(path if foreign or (swap and os.path.ismount(path)) else path.parent)


def check_can_create_in(folder: Path) -> None:
    """An :class:`InputError` unless a file can be created in ``folder`` or, where it does not exist
    yet, in its nearest existing ancestor: a file there, no permission, a read-only file system
    (which ``os.access`` does not tell root)."""
    while not os.path.lexists(folder) and folder != folder.parent:
        folder = folder.parent  # (a dangling link stops the climb: it is no folder)
    if not folder.is_dir():
        raise InputError("cannot write: a file is where a folder would be", path=folder)
    try:
        read_only = bool(os.statvfs(folder).f_flag & os.ST_RDONLY)
    except OSError:
        read_only = False
    if read_only:       # (first: access() fails there too, and "permission denied" misled root)
        raise InputError("cannot write: read-only file system", path=folder)
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError("cannot write: permission denied", path=folder)


@contextlib.contextmanager
def atomic_dir(path: str | os.PathLike, replace: Callable[[Path], bool] | None = None,
               outputs: Iterable[str] = ()) -> Iterator[Path]:
    """Yield a temporary folder in which to write the outputs that belong in the folder ``path``.

    When ``path`` does not exist or is empty, the temporary folder (next to it) is renamed onto
    ``path`` when the block succeeds and removed when it fails: a failed or interrupted command
    leaves no folder. When ``path`` is a folder of earlier outputs that ``replace(path)`` says are
    this program's own (e.g. a finished run), the new outputs are built the same way and then
    swapped in for the old ones. Into any other existing folder the outputs are moved one by one
    when the block succeeds, and never over a file or folder already there (the program did not
    create it): ``outputs``, the names the block will write, are checked before it runs, and
    every name it wrote is checked again before anything is moved (:class:`InputError`)."""
    path, swap, foreign = _plan_dir(path, replace, outputs)
    in_place = foreign or (swap and os.path.ismount(path))   # a mount point cannot be renamed
    folders: list[Path] = []         # the folders created to hold it
    _prepare(path, folders, is_folder=True)
    made: list[Path] = []            # the temporary folder
    kept: list[Path] = []            # where the earlier outputs wait while a swap renames
    swapped = False                  # the earlier outputs are out of ``path``
    try:
        with _undone_on_failure(path, made, folders):
            tmp = _fresh(path if in_place else path.parent, f".{path.name}.", ".tmp", True, made)
            yield tmp
            if in_place:
                _move_in(tmp, path, swap, kept)
                return
            if swap:
                old = _fresh(path.parent, f".{path.name}.", ".old.tmp", True, kept)
                mode = os.stat(path)
                swapped = True           # set first: an interruption inside the rename is covered
                os.replace(path, old)
            os.replace(tmp, path)           # onto an empty folder too (POSIX rename)
            swapped = False                 # the new outputs are in: the earlier ones go
            if swap:                        # the folder keeps the mode and owner it had
                with contextlib.suppress(OSError):
                    os.chmod(path, stat.S_IMODE(mode.st_mode))
                    os.chown(path, mode.st_uid, mode.st_gid)
    finally:
        if swapped and not os.path.lexists(path):
            with contextlib.suppress(OSError):
                os.replace(kept[0], path)         # put the earlier outputs back
        # the earlier outputs, swapped out, are removed whole: a signal meanwhile (handed on after)
        # cut the removal and left them hidden beside the new ones for good
        with signals_held(enabled=bool(kept)):
            _discard(kept)


def _move_in(tmp: Path, path: Path, swap: bool, kept: list[Path]) -> None:
    """Move the new outputs from ``tmp`` (inside ``path``) into ``path``, never over a name there;
    with ``swap``, the earlier outputs in ``path`` are first moved aside into a folder of ``kept``
    (inside ``path``). All or nothing: on a failure or an interruption the new outputs moved so
    far are taken out again and the earlier ones put back."""
    names = sorted(p.name for p in tmp.iterdir())
    aside: list[str] = []
    moved: list[str] = []
    try:
        if swap:
            old = _fresh(path, f".{path.name}.", ".old.tmp", True, kept)
            for p in sorted(path.iterdir()):
                if p not in (tmp, old):
                    aside.append(p.name)
                    os.rename(p, old / p.name)
        _check_free(path, names)
        for name in names:
            moved.append(name)
            try:
                _move_new(tmp / name, path / name)
            except (FileExistsError, InputError):
                moved.pop()             # the name another writer made: not ours to take out
                raise
        tmp.rmdir()
    except BaseException:
        for name in moved:
            _discard([path / name])
        for name in aside:
            with contextlib.suppress(OSError):
                os.rename(kept[0] / name, path / name)
        if kept and kept[0].is_dir() and any(kept[0].iterdir()):
            kept.clear()        # an earlier output that could not be put back stays where it waits
        raise


def outputs_of(marker: str, names: str | Iterable[str], keys: Iterable[str] = (),
               accept: Callable[[dict], bool] | None = None, inside: dict[str, str] | None = None
               ) -> Callable[[Path], bool]:
    """A ``replace`` test for :func:`atomic_dir`: the folder holds the JSON object ``marker`` (with
    ``keys``, and that ``accept`` takes if given), written by the same command before, and otherwise
    only the command's other outputs: ``names``, a regular expression or the names themselves.
    Those are files, but for the folders ``inside`` names, which hold only files whose names match
    its regular expression (what the command writes there): a file of the user's own put in one of
    them, or a folder where a file was written, is not an earlier output, and nothing is replaced."""
    if isinstance(names, str):
        pattern = re.compile(names)
        allowed: Callable[[str], bool] = lambda n: pattern.fullmatch(n) is not None   # noqa: E731
    else:
        allowed = set(names).__contains__
    want = tuple(keys)
    folders = {name: re.compile(rx) for name, rx in (inside or {}).items()}

    def ours(entry: Path) -> bool:
        if entry.name == marker:
            return True
        if not allowed(entry.name):
            return False
        if entry.name not in folders:
            return not entry.is_dir() or entry.is_symlink()
        if entry.is_symlink() or not entry.is_dir():
            return False
        return all(folders[entry.name].fullmatch(f.name) is not None and f.is_file() and not f.is_symlink()
                   for f in entry.iterdir())

    def test(folder: Path) -> bool:
        try:
            entries = list(folder.iterdir())
            if marker not in {p.name for p in entries} or not all(ours(p) for p in entries):
                return False
        except OSError:
            return False
        try:
            with open(folder / marker, encoding="utf-8") as fh:
                data = json.load(fh)
        except (OSError, ValueError, RecursionError):
            return False
        return isinstance(data, dict) and all(k in data for k in want) and (accept is None or accept(data))

    return test


def _claim(src: Path, dst: Path) -> None:
    """Move ``src`` to the name ``dst``, which must not exist (another writer may just have made
    it: a check before a rename does not hold it), else :class:`FileExistsError`: a file is linked
    there and unlinked (a link never replaces a name), a folder claims the name with an empty
    folder and is renamed onto it. Where the file system has no hard links (FAT, exFAT) the file is
    renamed unless the name exists."""
    if src.is_dir() and not src.is_symlink():
        os.mkdir(dst)
        try:
            os.rename(src, dst)
        except BaseException:
            with contextlib.suppress(OSError):
                os.rmdir(dst)
            raise
        return
    try:
        os.link(src, dst, follow_symlinks=False)
    except FileExistsError:
        raise
    except OSError:
        if os.path.lexists(dst):
            raise FileExistsError(errno.EEXIST, "File exists", os.fspath(dst)) from None
        os.rename(src, dst)
        return
    os.unlink(src)


def _move_new(src: Path, dst: Path) -> None:
    """:func:`_claim`, an existing ``dst`` said as the :class:`InputError` of :func:`_check_free`."""
    try:
        _claim(src, dst)
    except FileExistsError:
        _check_free(dst.parent, [dst.name])
        raise


def _check_free(folder: Path, names: Iterable[str]) -> None:
    """An :class:`InputError` naming the first of ``names`` that already exists in ``folder`` (a
    folder that is not only the command's earlier outputs: nothing in it is replaced), and what
    else the folder holds."""
    names = list(names)
    for name in names:
        if os.path.lexists(folder / name):
            try:
                others = sorted(p.name for p in folder.iterdir()
                                if p.name not in names and not _temporary(p.name, folder.name))
            except OSError:
                others = []
            held = (f" (it also holds {', '.join(others[:3])}{', …' if len(others) > 3 else ''})" if others
                    else "")
            raise InputError(f"exists, in a folder that is not only this command's earlier outputs{held}: "
                             "nothing in it is replaced; choose another output folder or move it away",
                             path=folder / name)


def _temporary(name: str, of: str) -> bool:
    """``name`` is one of the temporary names :func:`atomic_dir` makes for the folder ``of``."""
    return name.startswith(_fitting(f".{of}.", ".tmp")[0]) and name.endswith(".tmp")


def stale_dirs(path: str | os.PathLike) -> list[Path]:
    """The folders :func:`atomic_dir` was building next to ``path`` when the process writing them
    was killed (``.NAME.xxxxxxxx.tmp``; not ``.old.tmp``, which may hold the previous outputs):
    nothing else writes such names. Remove them only when no writer of ``path`` can still run."""
    path = Path(path)
    prefix = _fitting(f".{path.name}.", ".tmp")[0]    # (cut as _fresh cuts a long name's)
    pattern = re.compile(re.escape(prefix) + r"[a-z0-9_]{8}\.tmp")
    if not path.parent.is_dir():
        return []
    return [p for p in path.parent.glob(f"{glob.escape(prefix)}*.tmp") if p.is_dir() and pattern.fullmatch(p.name)]


def save_figure(fig, path: str | os.PathLike, dpi: int = 90, **savefig_kw) -> Path:
    """Save a matplotlib figure atomically (format from the suffix, PNG by default) and close it."""
    import matplotlib.pyplot as plt

    path = as_path(path, "a figure")
    fmt = path.suffix.lstrip(".").lower() or "png"
    try:
        from matplotlib.backend_bases import FigureCanvasBase

        if fmt not in FigureCanvasBase.get_supported_filetypes():   # (what any backend can write, not this one)
            raise InputError(f"matplotlib cannot write .{fmt} figures (e.g. .png, .pdf, .svg)", path=path)
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=dpi, format=fmt, **savefig_kw)
    finally:
        plt.close(fig)
    return path
