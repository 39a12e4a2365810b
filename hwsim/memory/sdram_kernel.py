"""The cycle-exact SDRAM controller's request loop, compiled (numba).

One function, :func:`schedule_requests` (with the refresh it inlines), is the whole
scheduling rule set of :mod:`hwsim.memory.sdram_cycle` (its module docstring states the
rules); the :class:`~hwsim.memory.SdramController` keeps the state in a few integer arrays
and calls it for every batch of requests.  The cycle rung's VolumePro/EM-Cube and VIZARD
II memories and the transaction rung's SDRAM port all schedule through it, so it sets much
of their speed: a few tens of nanoseconds a burst compiled, about half a microsecond as
Python.
``schedule_requests.py_func`` is the same code uncompiled (the tests run both).
The passes that count a schedule's outcomes and data-bus gaps (:func:`outcomes`,
:func:`outcomes_and_gaps`, and :func:`log_counts` straight from a controller's logs)
are compiled here too.

Command-bus bookkeeping: one command per cycle is kept as a short list of the cycles
already booked at or after the controller's admission point (``floor``).  After request
``i`` every later command and every later query lies at or after request ``i``'s
admission cycle (a later refresh starts at its due cycle, which is past that floor; every
other command waits for the floor), so booked cycles before it can never matter again and
are dropped after each request: the list holds the few commands issued ahead of the floor.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = [
    "BANK_ROWS",
    "CONFLICT",
    "HIT",
    "MISS",
    "OUT_ROWS",
    "PARAMS",
    "REGS",
    "log_counts",
    "outcomes",
    "outcomes_and_gaps",
    "schedule_requests",
]

#: Row outcome codes of :attr:`~hwsim.memory.sdram_cycle.BurstSchedule.outcome`.
HIT, MISS, CONFLICT = 0, 1, 2

#: Order of the timing parameters in the ``params`` array.
PARAMS = (
    "t_rcd",
    "t_rp",
    "t_ras",
    "t_rc",
    "t_rrd",
    "burst_cycles",
    "read_to_precharge",
    "t_rfc",
    "t_refi",
    "closed_page",
    "queue_depth",
    "command_bus",
)
#: Scalar registers in ``regs``: the controller state plus the fill of the two logs.
REGS = ("last_act", "prev_read", "last_ref", "refresh_end", "due", "floor", "booked", "refreshes")
#: Rows of ``bank_state`` (one column per bank).
BANK_ROWS = ("open_row", "act_at", "act_ready", "read_at")
#: Rows of ``out`` (one column per request): READ, ACTIVATE (-1 none), PRECHARGE (-1
#: none), refreshed-before flag (0/1).
OUT_ROWS = ("read", "activate", "precharge", "refreshed_before")


@numba.njit(cache=True, nogil=True)
def _is_booked(booked, n_booked, cycle):
    for k in range(n_booked):
        if booked[k] == cycle:
            return True
    return False


@numba.njit(cache=True, nogil=True)
def _book(booked, n_booked, cycle, command_bus):
    """Book ``cycle`` (if the command bus is modelled); returns the new fill."""
    if command_bus:
        booked[n_booked] = cycle
        return n_booked + 1
    return n_booked


@numba.njit(cache=True, nogil=True)
def _grown(arr):
    """A copy of ``arr`` with twice the rows (the logs grow inside the loop)."""
    bigger = np.zeros((2 * arr.shape[0],) + arr.shape[1:], dtype=arr.dtype)
    bigger[: arr.shape[0]] = arr
    return bigger


@numba.njit(cache=True, nogil=True)
def _first_free(booked, n_booked, cycle):
    while _is_booked(booked, n_booked, cycle):
        cycle += 1
    return cycle


@numba.njit(cache=True, nogil=True)
def _issue(booked, n_booked, cycle, command_bus):
    """Issue a command wanted at ``cycle`` on the first cycle from there with the command
    bus free, and book it; returns ``(its cycle, booked fill)``."""
    cycle = _first_free(booked, n_booked, cycle)
    return cycle, _book(booked, n_booked, cycle, command_bus)


# Inlined into schedule_requests at Numba IR level (``inline="always"``), so it costs no
# call.  An array handed to an inlined function is reference counted (an atomic add) on
# each call: once per refresh is cheap, once per request would not be (about 10% of the loop),
# so the per-request path stays in schedule_requests and calls only plain functions
# (_issue), which LLVM inlines.
@numba.njit(cache=True, nogil=True, inline="always")
def _refresh(params, bank_state, booked, n_booked, due, prev_read, last_ref):
    """Book the refresh due at ``due``: after every command issued so far (possibly while
    the controller sat idle), all banks precharged (one PRECHARGE-ALL if a row is open),
    then REFRESH; every bank closes until tRFC after it.  Returns ``(PRECHARGE-ALL cycle or
    -1, REFRESH cycle, booked fill)``; ``booked`` must have room for two more."""
    t_rp, t_ras, rtp, t_rfc = params[1], params[2], params[6], params[7]
    command_bus = params[11] != 0
    open_row, act_at = bank_state[0], bank_state[1]
    act_ready, read_at = bank_state[2], bank_state[3]
    begin = max(due, prev_read + 1, last_ref + 1)
    prea = -1
    any_open = False
    for q in range(open_row.shape[0]):
        if open_row[q] >= 0:
            any_open = True
            begin = max(begin, act_at[q] + t_ras, read_at[q] + rtp)
    if any_open:
        prea, n_booked = _issue(booked, n_booked, begin, command_bus)
        begin = prea + t_rp
    for q in range(open_row.shape[0]):
        begin = max(begin, act_ready[q])
    ref, n_booked = _issue(booked, n_booked, begin, command_bus)
    for q in range(open_row.shape[0]):
        open_row[q] = -1
        act_ready[q] = ref + t_rfc
    return prea, ref, n_booked


@numba.njit(cache=True, nogil=True)
def schedule_requests(params, regs, bank_state, banks, rows, arrive, out, start, booked, log):
    """Schedule requests ``banks[j], rows[j], arrive[j]`` as request ``start + j`` onwards.

    Writes each request's command cycles into ``out[:, start + j]`` and refreshes into
    ``log``; updates ``regs`` and ``bank_state``.  Returns ``(booked, log)``: the same
    arrays, or larger copies where they filled up.
    """
    t_rcd, t_rp, t_ras, t_rc, t_rrd = params[0], params[1], params[2], params[3], params[4]
    bc, rtp, t_rfc, t_refi = params[5], params[6], params[7], params[8]
    closed, depth, command_bus = params[9] != 0, params[10], params[11] != 0
    last_act, prev_read, last_ref, refresh_end = regs[0], regs[1], regs[2], regs[3]
    due, floor, n_booked, n_ref = regs[4], regs[5], regs[6], regs[7]
    # ``bank_state`` and ``out`` indexed in two dimensions, no row views: a view costs
    # two reference counts (atomic) a call, and a call is a dozen requests (VIZARD II).
    for j in range(banks.shape[0]):
        i = start + j
        b, r = banks[j], rows[j]
        # Admitted in order, on arrival, once the request ``depth`` ahead has left the queue.
        floor = max(floor, arrive[j], out[0, i - depth] + 1 if i >= depth else floor)
        out[3, i] = 1 if floor >= due else 0
        while floor >= due:
            if n_ref == log.shape[0]:
                log = _grown(log)
            if n_booked + 2 > booked.shape[0]:
                booked = _grown(booked)
            prea, last_ref, n_booked = _refresh(
                params, bank_state, booked, n_booked, due, prev_read, last_ref
            )
            log[n_ref, 0], log[n_ref, 1] = prea, last_ref
            n_ref += 1
            refresh_end = last_ref + t_rfc
            due += t_refi
            floor = max(floor, refresh_end)
        if n_booked + 3 > booked.shape[0]:
            booked = _grown(booked)
        out[1, i] = out[2, i] = -1
        act_at = bank_state[1, b]
        if bank_state[0, b] == r:  # row hit: READ only
            t = max(act_at + t_rcd, floor, prev_read + bc)
        else:
            if bank_state[0, b] < 0:  # row miss
                t = max(bank_state[2, b], floor)
            else:  # row conflict: PRECHARGE first
                t = max(act_at + t_ras, floor, bank_state[3, b] + rtp)
                t, n_booked = _issue(booked, n_booked, t, command_bus)
                out[2, i] = t
                t += t_rp
            t = max(t, act_at + t_rc, last_act + t_rrd)
            last_act, n_booked = _issue(booked, n_booked, t, command_bus)
            out[1, i] = bank_state[1, b] = act_at = last_act
            t = max(last_act + t_rcd, prev_read + bc)
        prev_read, n_booked = _issue(booked, n_booked, t, command_bus)
        out[0, i] = bank_state[3, b] = prev_read
        if closed:
            bank_state[2, b] = max(prev_read + rtp, act_at + t_ras) + t_rp
        else:
            bank_state[0, b] = r
        kept = 0  # drop booked cycles before this admission: none can matter again
        for q in range(n_booked):
            if booked[q] >= floor:
                booked[kept] = booked[q]
                kept += 1
        n_booked = kept

    regs[0], regs[1], regs[2], regs[3] = last_act, prev_read, last_ref, refresh_end
    regs[4], regs[5], regs[6], regs[7] = due, floor, n_booked, n_ref
    return booked, log


def empty_out(capacity: int) -> np.ndarray:
    """An ``out`` array for ``capacity`` requests."""
    return np.zeros((len(OUT_ROWS), max(capacity, 1)), dtype=np.int64)


@numba.njit(cache=True, nogil=True)
def outcomes(activate, precharge):
    """Each request's outcome code from its ACTIVATE and PRECHARGE cycles (-1: none):
    :data:`HIT` without an ACTIVATE, :data:`CONFLICT` with both, else :data:`MISS`.  One
    compiled pass: NumPy's three masked writes cost ~8 ns a request (2 ms a VIZARD II
    frame at 128^3)."""
    outcome = np.empty(activate.shape[0], np.int8)
    for i in range(activate.shape[0]):
        outcome[i] = _outcome(activate[i], precharge[i])
    return outcome


@numba.njit(cache=True, nogil=True)
def _outcome(activate, precharge):
    return HIT if activate < 0 else CONFLICT if precharge >= 0 else MISS


@numba.njit(cache=True, nogil=True)
def _gap_cause(o, earliest, read, refreshed, miss_lat, conflict_lat):
    """Stall a data-bus gap before a burst is charged to (0 arrival, 1 bank, 2 refresh):
    arrival when its READ could not issue earlier even with its bank ready (``earliest
    + row latency >= read``), else refresh when a refresh came just before it."""
    could = np.int64(earliest) + (0 if o == HIT else miss_lat if o == MISS else conflict_lat)
    return 0 if could >= read else 2 if refreshed else 1


@numba.njit(cache=True, nogil=True)
def log_counts(out, earliest, n, bc, miss_lat, conflict_lat):
    """:func:`outcomes_and_gaps` of a controller's first ``n`` logged requests (``out``
    rows READ, ACTIVATE, PRECHARGE, refreshed-before), their outcomes formed on the way."""
    counts = np.zeros(3, np.int64)
    stalls = np.zeros(3, np.int64)  # arrival, bank, refresh
    for i in range(n):
        o = _outcome(out[1, i], out[2, i])
        counts[o] += 1
        gap = out[0, i] - out[0, i - 1] - bc if i else 0
        if gap > 0:
            stalls[
                _gap_cause(o, earliest[i], out[0, i], out[3, i] != 0, miss_lat, conflict_lat)
            ] += gap
    return counts, stalls


@numba.njit(cache=True, nogil=True)
def outcomes_and_gaps(read, outcome, earliest, refreshed, bc, miss_lat, conflict_lat):
    """One pass of :func:`~hwsim.memory.sdram_cycle.summarize` over the requests: the
    count of each outcome and the data-bus gaps before bursts ``i > 0`` (``read[i] -
    read[i-1] - bc`` when positive) summed by cause (:func:`_gap_cause`).  Compiled: in
    NumPy these were a dozen passes and temporaries a request."""
    counts = np.zeros(3, np.int64)
    stalls = np.zeros(3, np.int64)  # arrival, bank, refresh
    for i in range(read.shape[0]):
        o = outcome[i]
        if o < 0 or o > 2:
            raise ValueError("outcome codes are HIT, MISS or CONFLICT (0, 1, 2)")
        counts[o] += 1
        if i == 0:
            continue
        gap = read[i] - read[i - 1] - bc
        if gap > 0:
            stalls[_gap_cause(o, earliest[i], read[i], refreshed[i], miss_lat, conflict_lat)] += gap
    return counts, stalls
