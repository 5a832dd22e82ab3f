"""Rollouts over a Dask cluster: evaluate a rollout function over many (params, seed) pairs, and a
cross-entropy method on top.

A rollout is a picklable callable ``rollout(params, seed) -> dict`` (Dask pickles it with
cloudpickle, so a lambda or a closure works too; it runs in worker processes, which import what it
uses, e.g. cartesian_impedance). It must be deterministic for its seed: the same (params, seed)
gives the same dict, wherever it runs.

- ``evaluate(rollout, pairs)``: the dicts in the order of ``pairs``, on a LocalCluster of worker
  processes started for the call (``n_workers``, one thread each), or on the cluster of a given
  ``distributed.Client`` (e.g. ``Client("tcp://scheduler:8786")``).
- ``Pool``: the same cluster kept for many calls (``with Pool(n_workers=2) as pool:
  pool.map(rollout, pairs)``), as ``cem`` does across its iterations.
- A worker process that dies while running a rollout (a crash in the simulation, the OOM killer)
  does not lose it: Dask reports the task as killed (or its finished result as lost) and it is
  submitted again, up to ``retries`` times. Each pair's result is taken once, from the run that
  completed.
- A rollout that raises ends the call with ``RolloutError`` naming the pair (index, params, seed)
  and carrying the worker's traceback; the remaining rollouts are cancelled. So does one that
  calls sys.exit() (SystemExit is the rollout's failure, not its worker's death), and one whose
  result cannot be pickled: each result is pickled on its worker, which names the keys that fail.

Needs dask.distributed (Debian: python3-distributed); it is imported when a cluster is used, so
``serial=True`` runs anywhere.
"""

import dataclasses
import logging
import os
import pickle
import traceback
import warnings
from typing import Any, Callable, Iterable, List, Optional, Sequence, Tuple

import numpy as np

__all__ = ["RolloutError", "Pool", "evaluate", "cem", "CemResult"]

Rollout = Callable[[Any, int], dict]


class RolloutError(RuntimeError):
    """A rollout that raised (or returned something other than a dict), or whose worker died
    more often than allowed. ``index``: the pair's position in the input; ``params``, ``seed``:
    the pair; ``remote_traceback``: the traceback text from the worker ('' if none). The original
    exception, when it could be pickled back, is the ``__cause__``."""

    def __init__(self, message, index, params, seed, remote_traceback=""):
        super().__init__(message)
        self.index = index
        self.params = params
        self.seed = seed
        self.remote_traceback = remote_traceback


def _run_chunk(rollout, chunk, pickled=False):
    """Each (params, seed) of the chunk, caught, so that an exception is reported for its pair
    instead of being retried by Dask (it would only repeat). ``pickled`` (on a worker): each
    result is pickled here, so that one that cannot be is reported as this pair's error; left to
    Dask, it fails in the worker's send, which logs tracebacks and leaves the task 'finished'
    with nothing to fetch."""
    records = []
    for params, seed in chunk:
        try:
            result = rollout(params, seed)
            if not isinstance(result, dict):
                raise TypeError("the rollout returned %s; a rollout returns a dict of results"
                                % type(result).__name__)
            records.append(("ok", _pickle_result(result) if pickled else result))
        except KeyboardInterrupt:
            raise  # the user stopping the program, not the rollout's failure
        # BaseException: a rollout calling sys.exit() (SystemExit) would otherwise escape a serial
        # run, and on a worker end the task as if its process had died, to be run again.
        except BaseException as error:  # noqa: BLE001  (reported to the caller, with its pair)
            try:
                pickle.loads(pickle.dumps(error))
                carried = error
            except Exception:  # noqa: BLE001  (not picklable: the text still says what it was)
                carried = None
            records.append(("error", "%s: %s" % (type(error).__name__, error),
                            traceback.format_exc(), carried))
            break  # the call ends at this error: the rest of the chunk would be thrown away
    return records


def _pickle_result(result: dict) -> bytes:
    """The result pickled as Dask would (cloudpickle); TypeError naming the keys whose values
    cannot be."""
    import cloudpickle

    try:
        return cloudpickle.dumps(result)
    except Exception as error:  # noqa: BLE001  (pickle raises many kinds)
        keys = []
        for key, value in result.items():
            try:
                cloudpickle.dumps(value)
            except Exception:  # noqa: BLE001
                keys.append(key)
        raise TypeError("the rollout's result cannot be pickled to be sent back from its worker "
                        "(%s: %s); the values of %s cannot be pickled" % (
                            type(error).__name__, error,
                            ", ".join(repr(key) for key in keys) or "no single key")) from None


def _is_int(value) -> bool:
    """An int or a NumPy integer, not a bool (True is an int to Python, not a count to a user)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _pair_text(params, seed):
    text = repr(params)
    if len(text) > 200:
        text = text[:200] + "..."
    return "params=%s, seed=%r" % (text, seed)


def _as_pairs(pairs) -> List[Tuple[Any, int]]:
    listed = []
    for index, pair in enumerate(pairs):
        try:
            params, seed = pair
        except (TypeError, ValueError):
            raise TypeError("pairs[%d] must be a pair (params, seed), got %r" % (index, pair)) \
                from None
        listed.append((params, seed))
    return listed


def _raise_for(record, index, params, seed):
    _, message, remote_traceback, carried = record
    error = RolloutError("rollout %d (%s) raised %s\n--- worker traceback ---\n%s"
                         % (index, _pair_text(params, seed), message, remote_traceback),
                         index, params, seed, remote_traceback)
    raise error from carried


def _name_what_cannot_be_pickled(rollout, listed):
    """After a submission failed: TypeError naming the rollout or the first pair that cannot be
    pickled (Dask's own error says only 'cannot pickle <type>'); returns if both can."""
    import cloudpickle

    try:
        cloudpickle.dumps(rollout)
    except Exception as error:  # noqa: BLE001
        raise TypeError("the rollout %r cannot be pickled to be sent to the workers (%s: %s); "
                        "what it refers to travels with it" % (
                            rollout, type(error).__name__, error)) from error
    for index, (params, seed) in enumerate(listed):
        try:
            cloudpickle.dumps((params, seed))
        except Exception as error:  # noqa: BLE001
            raise TypeError("pairs[%d] (%s) cannot be pickled to be sent to a worker (%s: %s)" % (
                index, _pair_text(params, seed), type(error).__name__, error)) from error


def _unpickle_result(payload, index, params, seed):
    try:
        return pickle.loads(payload)
    except Exception as error:  # noqa: BLE001  (e.g. a class this process cannot import)
        raise RolloutError("rollout %d (%s) returned a result its worker pickled but this "
                           "process cannot unpickle: %s: %s" % (
                               index, _pair_text(params, seed), type(error).__name__, error),
                           index, params, seed) from error


class Pool:
    """Where rollouts run: a LocalCluster of ``n_workers`` worker processes with one thread each,
    started here (default: one per CPU), or the cluster of the given ``client``
    (distributed.Client; it is not closed by close()). ``retries``: how many times a rollout
    whose worker process died is submitted again. ``serial=True``: no cluster, every rollout in
    this process, in order (for debugging, and the reference the parallel runs equal).

    A context manager: ``with Pool(n_workers=2) as pool: results = pool.map(rollout, pairs)``.
    One dropped without close() closes its LocalCluster then, with a ResourceWarning.
    """

    def __init__(self, client=None, *, n_workers: Optional[int] = None, retries: int = 3,
                 serial: bool = False):
        if not _is_int(retries) or retries < 0:
            raise ValueError("retries = %r must be an int >= 0" % (retries,))
        if n_workers is not None and (not _is_int(n_workers) or n_workers < 1):
            raise ValueError("n_workers = %r must be an int >= 1 (or None: one per CPU)"
                             % (n_workers,))
        if serial and client is not None:
            raise ValueError("serial=True runs in this process: give no client")
        self.retries = int(retries)
        self.serial = serial
        self._cluster = None
        self._client = client
        if serial or client is not None:
            return
        import dask
        import distributed

        # A worker that dies is handled here (map() resubmits its rollouts): the scheduler's
        # own rescheduling would run a rollout up to allowed-failures more times on top.
        with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
            self._cluster = distributed.LocalCluster(
                n_workers=int(n_workers or os.cpu_count() or 1), threads_per_worker=1,
                processes=True, dashboard_address=":0", silence_logs=logging.ERROR)
        try:
            self._client = distributed.Client(self._cluster)
        except BaseException:
            self._cluster.close()
            raise

    @property
    def client(self):
        """The distributed.Client (None when serial)."""
        return self._client

    def map(self, rollout: Rollout, pairs: Iterable[Tuple[Any, int]], *,
            chunk_size: int = 1) -> List[dict]:
        """rollout(params, seed) for each pair, the dicts in the input order. ``chunk_size``:
        rollouts per Dask task (more amortises Dask's per-task cost for short rollouts; a dead
        worker then reruns the whole chunk). Raises RolloutError naming the first pair that
        raised (the rest are cancelled), TypeError for a pair that is not (params, seed)."""
        if not callable(rollout):
            raise TypeError("rollout must be callable as rollout(params, seed) -> dict, got %r"
                            % (rollout,))
        if not _is_int(chunk_size) or chunk_size < 1:
            raise ValueError("chunk_size = %r must be an int >= 1" % (chunk_size,))
        chunk_size = int(chunk_size)
        listed = _as_pairs(pairs)
        if self.serial:
            results = []
            for index, (params, seed) in enumerate(listed):
                (record,) = _run_chunk(rollout, [(params, seed)])
                if record[0] != "ok":
                    _raise_for(record, index, params, seed)
                results.append(record[1])
            return results
        if self._client is None:
            raise RuntimeError("this Pool is closed")
        return self._map_on_cluster(rollout, listed, chunk_size)

    def _map_on_cluster(self, rollout, listed, chunk_size) -> list:
        import distributed
        from distributed.scheduler import KilledWorker

        starts = list(range(0, len(listed), chunk_size))
        chunks = [listed[start:start + chunk_size] for start in starts]
        attempts = [0] * len(chunks)
        pending = {}  # future -> chunk number
        completed = distributed.as_completed()

        def submit(number):
            # pure=False: every submission is a new task, also a resubmitted one.
            future = self._client.submit(_run_chunk, rollout, chunks[number], True,
                                         pure=False)
            pending[future] = number
            completed.add(future)

        def rerun(future, number):
            """A chunk whose worker died (KilledWorker), or whose result was lost with its
            worker after it finished: submitted again, or RolloutError once retries are spent."""
            error = future.exception() if future.status == "error" else None
            died = isinstance(error, KilledWorker) or future.status == "lost"
            if died and attempts[number] < self.retries:
                attempts[number] += 1
                future.cancel()
                submit(number)
                return
            start = starts[number]
            params, seed = chunks[number][0]
            if died:
                what = "its worker process died on each of its %d runs (retries=%d)" % (
                    attempts[number] + 1, self.retries)
            elif error is not None:
                what = "failed in Dask: %s: %s" % (type(error).__name__, error)
            else:
                what = "its Dask task ended %s (was the cluster closed?)" % future.status
            raise RolloutError("rollout %d (%s): %s" % (start, _pair_text(params, seed), what),
                               start, params, seed) from error

        results: List[Optional[dict]] = [None] * len(listed)
        try:
            # One message to the scheduler for all of them (submit() per chunk costs more).
            try:
                first = self._client.map(_run_chunk, [rollout] * len(chunks), chunks,
                                         [True] * len(chunks), pure=False)
            except Exception:
                _name_what_cannot_be_pickled(rollout, listed)
                raise
            for number, future in enumerate(first):
                pending[future] = number
                completed.add(future)
            for batch in completed.batches():
                finished = []
                for future in batch:
                    number = pending.pop(future)
                    if future.status == "finished":
                        finished.append((future, number))
                    else:
                        rerun(future, number)
                if not finished:
                    continue
                try:  # one fetch for the batch (a fetch per future costs a round trip each)
                    values = self._client.gather([future for future, _ in finished])
                except Exception:  # noqa: BLE001  (a result lost meanwhile: one by one)
                    values = None
                for position, (future, number) in enumerate(finished):
                    if values is None:
                        try:
                            records = future.result()
                        except Exception:  # noqa: BLE001  (rerun() names it if it cannot)
                            rerun(future, number)
                            continue
                    else:
                        records = values[position]
                    for offset, record in enumerate(records):
                        index = starts[number] + offset
                        if record[0] != "ok":
                            _raise_for(record, index, *listed[index])
                        results[index] = _unpickle_result(record[1], index, *listed[index])
        finally:
            for future in list(pending):
                future.cancel()
        return results

    def close(self):
        """Closes the client and the LocalCluster this Pool started (a given client stays)."""
        if self._cluster is not None:
            self._client.close()
            self._cluster.close()
            self._cluster = None
            self._client = None

    def __del__(self):
        # A Pool dropped unclosed would keep its worker processes until the interpreter exits.
        if getattr(self, "_cluster", None) is not None:
            warnings.warn("a rollouts.Pool was dropped without close(): closing its LocalCluster "
                          "(use `with Pool(...) as pool:`)", ResourceWarning, stacklevel=2)
            try:
                self.close()
            except Exception:  # noqa: BLE001  (interpreter shutdown)
                pass

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.close()

    def __repr__(self):
        if self.serial:
            return "Pool(serial)"
        if self._client is None:
            return "Pool(closed)"
        workers = len(self._client.scheduler_info().get("workers", {}))
        return "Pool(%s, %d workers, retries=%d)" % (
            "LocalCluster" if self._cluster is not None else "given client", workers,
            self.retries)


def evaluate(rollout: Rollout, pairs: Iterable[Tuple[Any, int]], *, client=None,
             pool: Optional[Pool] = None, n_workers: Optional[int] = None, retries: int = 3,
             chunk_size: int = 1, serial: bool = False) -> List[dict]:
    """rollout(params, seed) for each (params, seed) pair, the dicts in the input order: on
    ``pool``, on the cluster of ``client``, or on a LocalCluster of ``n_workers`` processes started
    and closed for this call (a few seconds: keep a Pool for many calls). See Pool and Pool.map."""
    if pool is not None:
        if client is not None or serial:
            raise ValueError("give a pool, or a client / serial=True, not both")
        return pool.map(rollout, pairs, chunk_size=chunk_size)
    with Pool(client, n_workers=n_workers, retries=retries, serial=serial) as own:
        return own.map(rollout, pairs, chunk_size=chunk_size)


@dataclasses.dataclass
class CemResult:
    """What cem() found: ``mean`` and ``std`` of the final sampling distribution, the best
    sample seen (``best_params``, ``best_score``, ``best_result``: its rollout's dict), and per
    iteration ``history``: dicts with mean, std, the elite's mean score, the best score and
    ``unscored``, how many of the population were scored NaN (all of them: NaN scores, and the
    distribution stayed)."""

    mean: np.ndarray
    std: np.ndarray
    best_params: np.ndarray
    best_score: float
    best_result: dict
    history: List[dict]


def _score_value(score_of, score, result) -> float:
    """The result's score as a float (NaN allowed: that rollout counts as unscored); ValueError
    naming the score for anything that is not one real number."""
    try:
        value = score_of(result)
        if np.iscomplexobj(value) or isinstance(value, (str, bytes)):
            # float() of a NumPy complex drops the imaginary part with only a warning.
            raise TypeError("%r is not a real number" % (value,))
        return float(value)
    except (KeyError, TypeError, ValueError, IndexError) as error:
        raise ValueError("score %r could not be read from a rollout's result (%s: %s); "
                         "a result: %r" % (score, type(error).__name__, error, result)) from error


def _real_vector(name, values) -> np.ndarray:
    """`values` as a float64 vector; TypeError naming `name` for a dtype that is not real numbers
    (float() of a complex would drop its imaginary part with only a warning, None be NaN)."""
    array = np.asarray(values)
    if array.dtype.kind not in "fiu":
        raise TypeError("%s = %r must be real numbers (an integer or float dtype), got dtype %s"
                        % (name, values, array.dtype))
    return np.array(array, dtype=float).reshape(-1)


def cem(rollout: Rollout, mean: Any, std: Any, *, iterations: int = 10,
        population: int = 32, elite_fraction: float = 0.25, score: Any = "score",
        maximize: bool = True, std_smoothing: float = 0.5, min_std: float = 0.0, seed: int = 0,
        pool: Optional[Pool] = None,
        client=None, n_workers: Optional[int] = None, retries: int = 3, chunk_size: int = 1,
        serial: bool = False) -> CemResult:
    """The cross-entropy method over a parameter vector: each iteration samples ``population``
    vectors from N(mean, diag(std^2)), evaluates rollout(params, seed) for each (through
    evaluate(), so on a cluster; params a float64 array), keeps the best ``elite_fraction`` by
    their score and moves the mean to theirs and the std toward theirs: std_smoothing * std +
    (1 - std_smoothing) * the elite's std, at least ``min_std``. The plain method
    (std_smoothing=0) often shrinks the std to nothing before the mean has arrived (on a
    3-dimensional quadratic, a quarter of the runs stop 0.1 to 1.7 away from the optimum); with
    0.5 it arrives (within 0.005 in 500 runs of 20 iterations).

    ``score``: the key of the rollout's dict to rank by, or a callable dict -> float; higher is
    better with ``maximize`` (lower without). A NaN score marks a rollout that could not be
    scored: it is never in the elite nor the best; ValueError if nothing was scored in the whole
    run, or for a score that is not one real number. ``seed`` fixes the samples and the
    rollouts' seeds, so a run is reproducible, serial or on any cluster. The pool (or the
    LocalCluster started here) is kept across iterations."""
    mean, std = _real_vector("mean", mean), _real_vector("std", std)
    if mean.shape != std.shape or mean.size == 0:
        raise ValueError("mean has shape %s and std %s: give two vectors of the same length >= 1"
                         % (mean.shape, std.shape))
    if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(std)) and np.all(std >= 0)):
        raise ValueError("mean must be finite and std finite and >= 0; got mean=%s, std=%s"
                         % (mean, std))
    for name, count, least in (("iterations", iterations, 1), ("population", population, 2)):
        if not _is_int(count) or count < least:
            raise ValueError("%s = %r must be an int >= %d" % (name, count, least))
    for name, value, ok, bound in (
            ("elite_fraction", elite_fraction, lambda v: 0.0 < v <= 1.0, "in (0, 1]"),
            ("std_smoothing", std_smoothing, lambda v: 0.0 <= v < 1.0, "in [0, 1)"),
            ("min_std", min_std, lambda v: 0.0 <= v < np.inf, "finite and >= 0")):
        # A bool or a string compares (or fails to) in ways that hide the mistake.
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer,
                                                             np.floating)) or not ok(value):
            raise ValueError("%s = %r must be a number %s" % (name, value, bound))
    score_of = score if callable(score) else (lambda result: result[score])
    elite_count = max(1, int(round(elite_fraction * population)))
    rng = np.random.default_rng(seed)
    best = None  # (score, params, result)
    last_result = None
    history = []

    own = None
    if pool is None:
        own = pool = Pool(client, n_workers=n_workers, retries=retries, serial=serial)
    try:
        for _ in range(iterations):
            samples = mean + std * rng.standard_normal((population, mean.size))
            seeds = rng.integers(0, 2**31 - 1, size=population)
            results = pool.map(rollout, [(sample, int(s)) for sample, s in zip(samples, seeds)],
                               chunk_size=chunk_size)
            scores = np.array([_score_value(score_of, score, result) for result in results])
            last_result = results[0]
            # NaN (a rollout that could not be scored) is never elite nor best: a NaN best would
            # never be beaten (every comparison with it is False), and a population of NaN has
            # no elite to move to.
            scored = np.flatnonzero(~np.isnan(scores))
            if scored.size == 0:
                # Nothing to learn from: the distribution stays, the next draw tries again.
                history.append({"mean": mean.copy(), "std": std.copy(),
                                "elite_score": float("nan"), "best_score": float("nan"),
                                "unscored": population})
                continue
            order = np.argsort(-scores[scored] if maximize else scores[scored], kind="stable")
            ranked = scored[order]
            elite_ranks = ranked[:elite_count]  # fewer when fewer were scored
            elite = samples[elite_ranks]
            top = ranked[0]
            if best is None or (scores[top] > best[0] if maximize else scores[top] < best[0]):
                best = (float(scores[top]), samples[top].copy(), results[top])
            mean = elite.mean(axis=0)
            std = np.maximum(std_smoothing * std + (1.0 - std_smoothing) * elite.std(axis=0),
                             min_std)
            history.append({"mean": mean.copy(), "std": std.copy(),
                            "elite_score": float(scores[elite_ranks].mean()),
                            "best_score": float(scores[top]),
                            "unscored": population - int(scored.size)})
    finally:
        if own is not None:
            own.close()
    if best is None:
        raise ValueError("score %r was NaN for every one of the %d rollouts (%d iterations of %d): "
                         "nothing to rank; a result: %r" % (
                             score, iterations * population, iterations, population,
                             last_result))
    return CemResult(mean=mean, std=std, best_params=best[1], best_score=best[0],
                     best_result=best[2], history=history)
