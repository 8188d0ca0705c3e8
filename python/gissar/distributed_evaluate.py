"""`gissar evaluate` with its Monte-Carlo trials spread over Dask workers.

Trial k of an evaluation depends only on (seed, k) (gissar.evaluate_trials), so the trials are cut into chunks
of consecutive indices, each chunk runs on a worker (one process, one thread by default: the C++ core already
uses every core it is given), and the records are summarised as the serial run summarises them
(gissar.summarise_trials): the same table for the same seed, except seconds_per_fix (time).

The cluster: `client` (a dask.distributed.Client you manage), else `scheduler` (the address of a running
scheduler, e.g. "tcp://host:8786"), else an embedded LocalCluster of `workers` processes (default: one per
core) that lives for this call.
"""

import os as _os
import time as _time

from . import _core
from . import distributed as _dist


def _run_chunk(options, first, count):
    """Worker side: the records of trials first .. first + count - 1."""
    return _core.evaluate_trials({**options, "trial_first": first, "trial_count": count})


def trial_chunks(trials, chunk_trials):
    """(first, count) pairs covering trials 0 .. trials - 1 in chunks of at most chunk_trials."""
    if trials < 1 or chunk_trials < 1:
        raise ValueError("trials and chunk_trials must be >= 1")
    return [(first, min(chunk_trials, trials - first)) for first in range(0, trials, chunk_trials)]


def evaluate(*, client=None, scheduler=None, workers=None, chunk_trials=None, threads_per_worker=1, **kwargs):
    """Run `gissar evaluate` (keywords: the fields of gissar.evaluate_request_defaults(), e.g. dem, trials, seed,
    size_px, spacing_m) on Dask and return the summary dict of the serial gissar.evaluate. chunk_trials: trials per
    task (default: trials spread evenly, about four tasks per worker). With out_prefix, writes PREFIX.json,
    PREFIX_trials.csv and PREFIX_hist.png like the serial run."""
    options = {k: (_os.fspath(v) if k in ("scene", "dem", "out_prefix", "product") and v is not None else v)
               for k, v in kwargs.items()}
    options.pop("trial_first", None)
    options.pop("trial_count", None)
    defaults = _core.evaluate_request_defaults()
    trials = int(options.get("trials", defaults["trials"]))
    started = _time.monotonic()
    # The corridor's cluster handling (docs/distributed.md "Resuming and faults"): an unreachable scheduler
    # is an IoError within 20 s, a lost scheduler or a chunk whose workers all died an IoError saying which.
    client, cluster, owned = _dist._start_client(client, scheduler, workers, threads_per_worker)
    lost = False
    try:
        n_workers = max(1, len(client.scheduler_info().get("workers", {})) or (workers or 1))
        chunk = chunk_trials or max(1, -(-trials // (4 * n_workers)))
        chunks = trial_chunks(trials, chunk)
        futures = client.map(_run_chunk, [options] * len(chunks), [c[0] for c in chunks], [c[1] for c in chunks],
                             pure=False)
        records = []
        for (first, count), future in zip(chunks, futures):
            try:
                records += future.result()
            except Exception as e:  # noqa: BLE001 (gissar's own errors pass through unchanged)
                if isinstance(e, _core.Error):
                    raise
                lost = _dist._scheduler_lost(client, e)
                if lost:
                    raise _core.IoError(f"lost the Dask scheduler mid-run ({type(e).__name__}): no summary; run "
                                        f"again with a running scheduler ({client.scheduler.address})") from None
                reason = _dist._failure_reason(e, _dist._worker_memory_limits(client), "ran these trials")
                raise _core.IoError(f"trials {first}..{first + count - 1} failed: {reason}") from None
    finally:
        _dist._release_client(client, cluster, owned, lost)
    if options.get("out_prefix"):
        return _core.write_evaluation(options, records, _time.monotonic() - started)
    return _core.summarise_trials(options, records)
