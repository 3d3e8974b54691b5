"""Transactional output folders: check, lock, stage, swap into place.

A run never writes into its ``--out`` folder ``DIR`` directly. It

1. checks that ``DIR`` can be written (before any work): ``DIR`` is a folder or
   does not exist, and the folder that holds it is writable;
2. takes the lock ``DIR.lock`` (an ``flock`` on a file beside ``DIR``, released
   by the kernel if the process dies): a second run on the same ``DIR`` is
   refused with exit status 2;
3. writes everything into the staging folder ``DIR.staging``, which holds an
   ``INCOMPLETE`` note until the end (a killed run leaves it there, and ``DIR``
   untouched);
4. swaps ``DIR.staging`` and ``DIR`` in one atomic ``renameat2(RENAME_EXCHANGE)``
   (two renames where the kernel lacks it) and keeps the previous result as
   ``DIR.prev``.

So ``DIR`` is always either the complete result of one run or untouched. Input
errors (or any other exception) after the lock remove the staging folder and the
lock file: nothing is created or changed. The search checkpoint is not in the
staging folder but in ``DIR.partial/`` (:mod:`nlp.solve.checkpoint`), so ``--resume``
finds it after any interruption.
"""

from contextlib import contextmanager
import ctypes
import errno
import fcntl
import os
import shutil
import stat

from nlp.errors import InputError

__all__ = ["check_writable", "staging_path", "lock_path", "prev_path", "output_folder",
           "locked_folder", "INCOMPLETE", "INTERRUPTED"]

INCOMPLETE = "INCOMPLETE"   # note inside a staging folder until it is swapped into place
INTERRUPTED = "INTERRUPTED"  # note inside a committed folder whose search was interrupted
_CRASH_ENV = "FRF_NLP_TEST_CRASH"  # tests only: "commit" kills the process before the swap


def staging_path(out):
    """The staging folder of ``out``: ``out + '.staging'``."""
    return os.path.abspath(out) + ".staging"


def lock_path(out):
    """The lock file of ``out``: ``out + '.lock'``, beside it."""
    return os.path.abspath(out) + ".lock"


def prev_path(out):
    """Where the previous result of ``out`` is kept: ``out + '.prev'``."""
    return os.path.abspath(out) + ".prev"


def _writable_dir(path):
    """A folder this process may write, and whose owner has not made it read-only
    (root ignores permission bits, so a chmod a-w folder is refused explicitly)."""
    st = os.stat(path)
    return stat.S_ISDIR(st.st_mode) and os.access(path, os.W_OK | os.X_OK) \
        and bool(st.st_mode & stat.S_IWUSR)


def check_writable(out, key="--out", must_exist=False):
    """Raise InputError unless ``out`` can be (re)written by a transactional run.

    Creates nothing. ``must_exist`` for commands that rebuild an existing folder.
    """
    out = os.path.abspath(out)
    if os.path.lexists(out):
        if not os.path.isdir(out):
            raise InputError(out, key, "a folder (or a path that does not exist yet), "
                             "not a file")
        if not _writable_dir(out):
            raise InputError(out, key, "a writable folder (it is read-only)")
    elif must_exist:
        raise InputError(out, key, "an existing run folder")
    parent = os.path.dirname(out)
    while not os.path.lexists(parent):
        parent = os.path.dirname(parent)
    if not os.path.isdir(parent):
        raise InputError(out, key, f"a path inside folders, but {parent} is a file")
    if not _writable_dir(parent):
        raise InputError(out, key, f"a place where a folder can be written ({parent} is "
                         "read-only)")


class _Lock:
    """An exclusive, non-blocking flock on ``DIR.lock``; the file is removed on release."""

    def __init__(self, out):
        self.path = lock_path(out)
        self.fd = None

    def acquire(self, out):
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN):
                    os.close(fd)
                    raise
                try:
                    holder = os.read(fd, 64).decode(errors="replace").strip() or "?"
                finally:
                    os.close(fd)
                raise InputError(out, "--out", "a folder no other frf-nlp run is writing "
                                 f"(locked by {self.path}, process {holder}); wait for it "
                                 "or choose another --out") from None
            # the file may have been removed by its previous holder: lock the live one
            try:
                same = os.stat(self.path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                os.ftruncate(fd, 0)
                os.write(fd, str(os.getpid()).encode())
                self.fd = fd
                return
            os.close(fd)

    def release(self):
        if self.fd is not None:
            try:
                os.unlink(self.path)
            except FileNotFoundError:
                pass
            os.close(self.fd)  # closing releases the flock
            self.fd = None


_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _exchange(a, b):
    """Swap two paths atomically (Linux renameat2); False if unsupported."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP):
        return False
    raise OSError(err, os.strerror(err), b)


def _fsync_dir(path):
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _remove(path):
    """Remove a folder, file or link if it exists (an old DIR.prev)."""
    if os.path.isdir(path) and not os.path.islink(path):
        shutil.rmtree(path)
    elif os.path.lexists(path):
        os.unlink(path)


def _note(path, text):
    with open(path, "w") as fh:
        fh.write(text)


def _commit(stage, out, interrupted):
    """Swap the finished staging folder into ``out``; the old result becomes ``out.prev``."""
    os.unlink(os.path.join(stage, INCOMPLETE))
    if interrupted:
        _note(os.path.join(stage, INTERRUPTED),
              "The search was interrupted: this result comes from the starts that finished "
              "(see search.interrupted in result.json).\n")
    if os.environ.get(_CRASH_ENV) == "commit":  # tests: die with everything written, nothing swapped
        os.kill(os.getpid(), 9)
    prev = prev_path(out)
    if os.path.isdir(out):
        if not _exchange(stage, out):
            _remove(prev)
            os.rename(out, prev)
            os.rename(stage, out)
            _fsync_dir(os.path.dirname(out))
            return
        # stage now holds the previous result
        _remove(prev)
        os.rename(stage, prev)
    else:
        os.rename(stage, out)
    _fsync_dir(os.path.dirname(out))


@contextmanager
def output_folder(out, command="run"):
    """Lock ``out`` and yield a fresh staging folder to write the result into.

    On normal exit the staging folder replaces ``out`` (old result kept as
    ``out.prev``); set ``folder.interrupted = True`` on the yielded object to
    mark a partial result. An exception (input error, failed search, Ctrl-C
    before any result) removes everything this call created and leaves ``out``
    untouched. Only a killed process leaves the staging folder, with its
    ``INCOMPLETE`` note; the next run replaces it.
    """
    out = os.path.abspath(out)
    check_writable(out)
    made = _missing_parents(out)
    os.makedirs(os.path.dirname(out), exist_ok=True)
    lock = _Lock(out)
    lock.acquire(out)
    stage = staging_path(out)
    handle = _Folder(stage)
    try:
        _remove(stage)  # left by a killed run: it never became a result
        os.makedirs(stage)
        _note(os.path.join(stage, INCOMPLETE),
              f"frf-nlp {command} (process {os.getpid()}) is writing this folder, or was "
              f"stopped before finishing. The last complete result is in {out}.\n")
        try:
            yield handle
        except BaseException:
            # an input error, a failed search, Ctrl-C before any result, a crash: nothing
            # half-written stays (the search checkpoint lives apart, in DIR.partial/)
            shutil.rmtree(stage, ignore_errors=True)
            lock.release()
            for d in made:  # deepest first; only folders this call created
                try:
                    os.rmdir(d)
                except OSError:
                    break
            raise
        _commit(stage, out, handle.interrupted)
    finally:
        lock.release()


def _missing_parents(out):
    """Ancestors of ``out`` that do not exist yet, deepest first."""
    made = []
    d = os.path.dirname(out)
    while not os.path.lexists(d):
        made.append(d)
        d = os.path.dirname(d)
    return made


class _Folder(str):
    """The staging folder's path (a str), with an ``interrupted`` flag."""

    interrupted = False

    def __new__(cls, path):
        return super().__new__(cls, path)


@contextmanager
def locked_folder(out, key="DIR"):
    """Lock an existing result folder for an in-place rebuild (``frf-nlp report``)."""
    out = os.path.abspath(out)
    check_writable(out, key=key, must_exist=True)
    lock = _Lock(out)
    lock.acquire(out)
    try:
        yield out
    finally:
        lock.release()
