"""The executor interface and the recipe workers build their context from."""

import hashlib
import pickle
from nlp.solve.executors.threads import limit_blas_threads

__all__ = ["Setup", "Executor", "Stream", "TaskFailed", "batches"]

_UNSET = object()
_CONTEXTS = {}        # per worker process: Setup.key -> built context
_MAX_CONTEXTS = 4     # long-lived (Dask) workers keep only the latest few problems


class TaskFailed(RuntimeError):
    """A task raised in a worker, or a worker died; carries the worker's traceback text."""


class Setup:
    """How a worker gets the shared context of a batch of tasks (e.g. a built NLP).

    Parameters
    ----------
    build : callable, optional
        Module-level function; ``build(*args, **kwargs)`` returns the context.
        It travels to remote workers by pickle (with its arguments), so a
        worker rebuilds the context once; compiled CasADi code is found in the
        worker's cache or compiled there from the generated source.
    value : object, optional
        The context already built in this process. Forked workers inherit it
        (no rebuild); it is never pickled.
    """

    def __init__(self, build=None, *args, value=_UNSET, **kwargs):
        if build is None and value is _UNSET:
            raise ValueError("Setup needs a build function or a value")
        self.build, self.args, self.kwargs = build, args, kwargs
        self.value = value
        self._key = None

    @property
    def has_recipe(self):
        return self.build is not None

    @property
    def key(self):
        """A hash of the recipe: workers cache one context per key."""
        if self._key is None:
            if self.build is None:
                self._key = f"value-{id(self.value)}"
            else:
                blob = pickle.dumps((self.build, self.args, self.kwargs), protocol=4)
                self._key = hashlib.sha256(blob).hexdigest()[:20]
        return self._key

    def get(self):
        """The context: the value given, else the one built in this process, else build it."""
        if self.value is not _UNSET:
            return self.value
        key = self.key
        if key not in _CONTEXTS:
            while len(_CONTEXTS) >= _MAX_CONTEXTS:
                _CONTEXTS.pop(next(iter(_CONTEXTS)))
            limit_blas_threads()  # a spawned or Dask worker: its parent's limit did not travel
            _CONTEXTS[key] = self.build(*self.args, **self.kwargs)
        return _CONTEXTS[key]

    def __getstate__(self):
        if self.build is None:
            raise TypeError("this Setup has no build recipe, so it cannot travel to another "
                            "process; give Setup(build, *args)")
        state = dict(self.__dict__)
        del state["value"]  # the built object stays here; the receiver builds its own
        state["_key"] = self.key
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self.value = _UNSET


def batches(items, size):
    """Consecutive slices of ``items`` of at most ``size``."""
    size = max(1, int(size))
    return [items[i:i + size] for i in range(0, len(items), size)]


class Stream:
    """Results of one submission, in completion order: iterate for ``(key, result)``."""

    def __iter__(self):
        return self

    def __next__(self):  # pragma: no cover - interface
        raise NotImplementedError

    def stop(self):
        """Stop all work now; return the ``(key, result)`` pairs that finished meanwhile."""
        return []

    def close(self):
        """Release workers; idempotent."""


class Executor:
    """Runs ``fn(context, item)`` for many items; see :mod:`nlp.solve.executors`."""

    kind = "base"
    workers = 1

    def stream(self, setup, fn, items, batch_size=None):  # pragma: no cover - interface
        """Start ``fn(setup.get(), item)`` for each ``(key, item)``; returns a :class:`Stream`."""
        raise NotImplementedError

    def map(self, setup, fn, items, batch_size=None):
        """All results as a dict ``key -> result`` (no streaming)."""
        s = self.stream(setup, fn, items, batch_size)
        try:
            return dict(s)
        finally:
            s.close()

    def close(self):
        """Release the executor's resources."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
