"""Output files that fail cleanly when the disk cannot take them.

A full disk (``ENOSPC``), a quota (``EDQUOT``), a read-only filesystem (``EROFS``), a
missing permission (``EACCES``, ``EPERM``) or a directory in place of the file
(``EISDIR``) ends a write with one :class:`OutputError`: an ``OSError`` whose message
names the file and the cause in one line, and which the commands report with exit
status 2 like any other input error.

The rule every writer of the project follows:

- a file is written as ``path + ".tmp"`` and renamed into place (:func:`publish`), or,
  for files that grow during a run (``fields.h5``, ``batch.h5``, the frames of
  ``dem run``), appended and flushed after every record;
- HDF5 files are opened through :class:`GuardedIO`: the HDF5 library writes through
  Python, so a failed write is seen as the ``OSError`` it is, and every later write of
  that file (HDF5's own clean-up when the file is closed) is dropped. Closing then
  succeeds, the library never holds a file it could not close, and no error of
  HDF5's reaches the user as a traceback or a crash;
- a ``.tmp`` file is removed whatever stopped its write; a file that grows in place
  keeps what it held at its last flush.

Checking the free space before a run is no help (the disk can fill during the run):
the writes themselves are checked.
"""

import contextlib
import errno
import io
import os

#: what to do about each cause, after the system's words for it
_ADVICE = {
    errno.ENOSPC: "(the disk is full); free space or choose another --output",
    errno.EDQUOT: "(the disk quota is used up); free space or choose another --output",
    errno.EROFS: "; choose another --output on a writable filesystem",
    errno.EACCES: "; choose another --output or change the directory's permissions",
    errno.EPERM: "; choose another --output or change the directory's permissions",
    errno.EISDIR: "; remove the directory or choose another --output",
    errno.EBUSY: "; wait for it to end or choose another --output",
}


class OutputError(OSError):
    """An output file could not be written; ``str()`` is one line naming the file
    and the cause, e.g. ``cannot write out/fields.h5: No space left on device (the
    disk is full); free space or choose another --output``.

    ``errno`` is the cause's, ``filename`` the file the user asked for (not its
    ``.tmp``).
    """

    def __init__(self, path, cause):
        code = getattr(cause, "errno", None)
        strerror = getattr(cause, "strerror", None)
        super().__init__(code, strerror or str(cause))
        self.filename = os.fspath(path)
        what = (strerror or os.strerror(code)) if code else " ".join(str(cause).split())
        advice = _ADVICE.get(code, "")
        sep = " " if advice.startswith("(") else ""
        self.message = f"cannot write {self.filename}: {what}{sep}{advice}"

    def __str__(self):
        return self.message


def output_error(path, cause):
    """``cause`` as an :class:`OutputError` for ``path`` (itself if it is one)."""
    return cause if isinstance(cause, OutputError) else OutputError(path, cause)


class GuardedIO(io.RawIOBase):
    """A file for h5py's file-object driver that remembers its first failed write.

    After a write, a truncation or a flush has failed (:attr:`error`), later writes
    are dropped and reported as done, so that HDF5 can close the file; what the file
    held at that moment stays on disk as it was.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    mode : str
        ``"w"`` creates or empties it, ``"r+"`` opens an existing one to change it.
    """

    def __init__(self, path, mode="w"):
        super().__init__()
        self.path = os.fspath(path)
        flags = os.O_RDWR | (os.O_CREAT if mode == "w" else 0)
        self._fh = open(os.open(self.path, flags, 0o666), "r+b", buffering=0)  # noqa: SIM115
        #: the first OSError of a write, or None
        self.error = None
        self._lock()  # before emptying it: a file another process writes is left alone
        if mode == "w":
            self._guarded(self._fh.truncate, 0)

    def _lock(self):
        """Hold the exclusive lock HDF5 itself takes on a file it writes, so that
        another process cannot write or read it half-done; skipped where HDF5 skips it
        (``HDF5_USE_FILE_LOCKING=FALSE``, a filesystem without locks)."""
        import fcntl

        if os.environ.get("HDF5_USE_FILE_LOCKING", "").upper() == "FALSE":
            return
        try:
            fcntl.flock(self._fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            self._fh.close()
            raise OSError(errno.EBUSY, "the file is open in another process") from None
        except OSError as err:
            if err.errno not in (errno.ENOSYS, errno.ENOLCK, errno.EOPNOTSUPP):
                self._fh.close()
                raise

    def readable(self):
        return True

    def writable(self):
        return True

    def seekable(self):
        return True

    def seek(self, pos, whence=0):
        return self._fh.seek(pos, whence)

    def tell(self):
        return self._fh.tell()

    def readinto(self, buffer):
        return self._fh.readinto(buffer)

    def _guarded(self, op, *args, done=None):
        if self.error is not None:
            return done
        try:
            return op(*args)
        except OSError as err:
            self.error = err
            raise

    def write(self, data):
        return self._guarded(self._write_all, data, done=len(data))

    def _write_all(self, data):
        """Write every byte: an unbuffered write may take only part of them (the
        last bytes a disk has room for), and h5py's driver does not ask again; the
        next attempt raises the cause."""
        view = memoryview(data).cast("B")
        done = 0
        while done < len(view):
            n = self._fh.write(view[done:])
            if not n:
                raise OSError(errno.EIO, f"{self.path}: a write took no bytes")
            done += n
        return done

    def truncate(self, size=None):
        return self._guarded(self._fh.truncate, size, done=size)

    def flush(self):
        if not self._fh.closed:
            self._guarded(self._fh.flush)

    def fsync(self):
        """Force the file to the disk (an error is remembered like a write's)."""
        self._guarded(os.fsync, self._fh.fileno())

    def close(self):
        if not self._fh.closed:
            try:
                self._fh.close()
            except OSError as err:
                self.error = self.error or err
        super().close()


class H5Output:
    """An HDF5 file being written, opened through :class:`GuardedIO`.

    ``h5`` is the ``h5py.File``. Use :meth:`failure` in an ``except`` clause: when
    a write has failed it closes the file (dropping HDF5's last writes) and returns
    the :class:`OutputError` to raise.

    Parameters
    ----------
    path : str or os.PathLike
        The file to open.
    mode : str
        ``"w"`` (create or replace) or ``"a"`` (append to an existing file, else
        create it).
    name : str or os.PathLike, optional
        The file to name in errors (default ``path``; a ``.tmp`` file names its
        target).
    """

    def __init__(self, path, mode="w", name=None):
        import h5py

        self.path = os.fspath(path)
        self.name = os.fspath(name or path)
        self.h5 = None
        self._closed = False
        mode = "r+" if mode == "a" and os.path.exists(self.path) else "w"
        try:
            self.io = GuardedIO(self.path, mode)
        except OSError as err:
            raise OutputError(self.name, err) from None
        try:
            self.h5 = h5py.File(self.io, mode)
        except BaseException as err:
            self.io.close()
            if self.io.error is not None:
                raise OutputError(self.name, self.io.error) from None
            raise err

    @property
    def failed(self):
        """Whether a write of this file has failed."""
        return self.io.error is not None

    def failure(self, err=None):
        """After an exception: None if no write failed (the exception is another
        matter); else the file closed and the :class:`OutputError` to raise."""
        if self.io.error is None and not isinstance(err, OutputError):
            return None
        self.abandon()
        return output_error(self.name, self.io.error or err)

    @contextlib.contextmanager
    def guard(self, on_failure):
        """A block of writes: if it raises after a write the disk refused, the file is
        closed, ``on_failure()`` (the writer's clean-up) called and the
        :class:`OutputError` raised instead; any other exception passes unchanged."""
        try:
            yield
        except BaseException as err:
            failure = self.failure(err)
            if failure is None:
                raise
            on_failure()
            raise failure from None

    def abandon(self):
        """Close the file without raising (writes after a failure are dropped)."""
        self._closed = True
        if self.h5 is not None:
            h5, self.h5 = self.h5, None
            with contextlib.suppress(Exception):
                h5.close()
        self.io.close()

    def close(self, sync=False):
        """Close the file (``sync``: first force it to the disk); OutputError if
        anything could not be written. Nothing to do once closed or abandoned."""
        if self._closed:
            return
        self._closed = True
        try:
            if self.h5 is not None:
                h5, self.h5 = self.h5, None
                h5.close()
            if sync:
                self.io.fsync()
        except BaseException as err:
            failure = self.failure(err)
            if failure is None:
                raise
            raise failure from None
        self.io.close()
        if self.io.error is not None:
            raise OutputError(self.name, self.io.error)


def readable_h5(path):
    """Whether ``path`` opens as an HDF5 file."""
    import h5py

    try:
        with h5py.File(path, "r"):
            return True
    except OSError:
        return False


def remove_quietly(path):
    """Remove ``path`` if it exists; an error (a read-only filesystem) is ignored."""
    with contextlib.suppress(OSError):
        os.remove(path)


def publish(tmp_path, path):
    """Atomically move a finished file ``tmp_path`` to ``path`` (fsync, then rename);
    OutputError naming ``path`` if either fails."""
    try:
        with open(tmp_path, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp_path, path)
    except OSError as err:
        raise OutputError(path, err) from None


def write_h5_atomic(path, fill):
    """Write the HDF5 file ``path`` with ``fill(h5file)`` into ``path + ".tmp"``,
    then :func:`publish` it. Whatever stops it, no ``.tmp`` is left; a failed write
    is an :class:`OutputError` naming ``path``. Returns ``path``."""
    path = os.fspath(path)
    tmp = path + ".tmp"
    try:
        out = H5Output(tmp, "w", name=path)
        try:
            fill(out.h5)
        except BaseException as err:
            failure = out.failure(err)
            out.abandon()
            if failure is None:
                raise
            raise failure from None
        out.close(sync=True)
        publish(tmp, path)
    finally:
        remove_quietly(tmp)
    return path


def write_bytes_atomic(path, write):
    """Write ``path`` through ``write(binary file)`` into ``path + ".tmp"``, then
    :func:`publish` it; no ``.tmp`` is left, a failed write is an
    :class:`OutputError` naming ``path``. Returns ``path``."""
    path = os.fspath(path)
    tmp = path + ".tmp"
    try:
        try:
            with open(tmp, "wb") as fh:
                write(fh)
        except OSError as err:
            raise output_error(path, err) from None
        publish(tmp, path)
    finally:
        remove_quietly(tmp)
    return path


def write_text_atomic(path, text):
    """:func:`write_bytes_atomic` of ``text`` encoded as UTF-8."""
    return write_bytes_atomic(path, lambda fh: fh.write(text.encode("utf-8")))
