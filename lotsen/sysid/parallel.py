"""Independent pieces of work on the cores the command gives: a map handed in, never a process started here.

The algorithms stay pure: an estimator takes `parallel`, a map with the signature of the built-in
`map(function, items)` (the default: the built-in, one core), and the command (lotsen.cli.workers)
hands it a map over its worker processes. The work is cut into pieces that do not depend on how many workers
there are, and whatever is summed over the pieces is summed here, in the pieces' order: the answer is
the same to the last digit with 1 and N workers (tests/sysid/test_parallel.py).

Large inputs that stay the same over many calls (a record's shooting intervals: ~1.5 MB for a 10-min
lake record, sent ~300 times by one identification) are `Held`: each worker keeps them after the first
call that needs them (`map_held`), so a call sends the parameters and the node states only.
"""

from __future__ import annotations

import itertools
import os
import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any, Callable, Generic, Iterable, Sequence, TypeVar

T = TypeVar("T")
R = TypeVar("R")

#: `map(function, items)`: the built-in (one core) or a pool's (multiprocessing.Pool.map,
#: concurrent.futures.Executor.map); the function is a module-level one, its items picklable
Map = Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]]
SERIAL: Map = map

#: how many held values a worker keeps (the newest): the blocks of a few identification problems
HELD_CAPACITY = 256
_tokens = itertools.count()
_held: "OrderedDict[tuple[int, int], Any]" = OrderedDict()
_held_lock = threading.Lock()  # a thread pool's workers share this process's store
_MISS = "lotsen.sysid.parallel: not held here"


@dataclass(frozen=True)
class Held(Generic[T]):
    """A value the workers keep between calls, known to them by its token (made in the caller)."""

    value: T
    token: tuple[int, int] = field(default_factory=lambda: (os.getpid(), next(_tokens)), compare=False)


def _call_held(task: tuple[Callable[[Any, Any], Any], tuple[int, int], Any, Any, bool]) -> Any:
    """In a worker: `function(value, argument)` with the value this worker holds under `token`, or the one
    sent along (then kept); the marker _MISS when neither (the caller sends it again with the value)."""
    function, token, value, argument, sent = task
    with _held_lock:
        if sent:
            _held[token] = value
            while len(_held) > HELD_CAPACITY:
                _held.popitem(last=False)
        elif token in _held:
            value = _held[token]
            _held.move_to_end(token)
        else:
            return _MISS
    return function(value, argument)


def map_held(parallel: Map, function: Callable[[T, Any], R], held: Sequence[Held[T]],
             arguments: Sequence[Any]) -> list[R]:
    """[function(h.value, a) for h, a in zip(held, arguments)] on `parallel`'s workers, in order. A
    worker that does not hold a value yet gets it with a second call (only the misses): after the first
    calls of a problem every call sends the arguments alone."""
    if len(held) != len(arguments):
        raise ValueError("one argument per held value")
    if parallel is SERIAL:
        return [function(h.value, a) for h, a in zip(held, arguments)]
    out = list(parallel(_call_held, [(function, h.token, None, a, False) for h, a in zip(held, arguments)]))
    missed = [i for i, r in enumerate(out) if isinstance(r, str) and r == _MISS]
    if missed:
        again = parallel(_call_held, [(function, held[i].token, held[i].value, arguments[i], True) for i in missed])
        for i, r in zip(missed, again):
            out[i] = r
    return out


def ordered_sum(parts: Iterable[Any]) -> Any:
    """The sum of `parts` in their order (arrays or numbers): one order whatever ran them."""
    it = iter(parts)
    total = next(it)
    total = total.copy() if hasattr(total, "copy") else total
    for p in it:
        total = total + p
    return total
