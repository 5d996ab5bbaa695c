"""The memory a process can still use, and the checks of a job against it before any work.

:func:`memory_limits` bounds the machine's available memory by the process's address-space limit
(``ulimit -v``) and its cgroup's; :func:`memory_available` is the smallest,
:func:`describe_memory` says it for messages. :func:`start_room` and :func:`check_basis_memory`
refuse a job that cannot fit before it starts. The memory modes of the factorizations are in
:mod:`flexmor.linalg.memory`.
"""

from __future__ import annotations

from ..errors import OutOfMemoryError

__all__ = ["ADDRESS_SPACE_OVERHEAD", "BASIS_COPIES", "MEMORY_FRACTION", "MEMORY_LIMIT_NAMES", "START_RESERVE", "bound",
           "check_basis_memory", "describe_memory", "megabytes", "memory_available", "memory_limits",
           "start_room"]

#: Refuse a job or factorization whose estimate exceeds this share of the available memory.
MEMORY_FRACTION = 0.9


def megabytes(x) -> str:
    """``"N MB"`` for messages."""
    return f"{x / 2**20:.0f} MB"


#: Address space kept free under an address-space limit, beyond what the data need: the BLAS
#: libraries' per-thread buffers (OpenBLAS and MKL take tens of MB per thread on first use, and
#: abort or spin when they cannot), the C library's per-thread heaps (reserved in 64 MB steps),
#: thread stacks. Measured: a dense eigen solve after a factorization that left ~120 MB spun
#: without end; 256 MB left, none did.
ADDRESS_SPACE_OVERHEAD = 256 * 2**20


def _proc_field(path: str, key: str) -> float | None:
    """The value in bytes of ``key:`` (given in kB) in a /proc file, or None."""
    try:
        with open(path) as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return 1024.0 * int(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return None


def _read_number(path: str) -> float | None:
    try:
        with open(path) as fh:
            text = fh.read().strip()
        return None if text in ("", "max") else float(text)
    except (OSError, ValueError):
        return None


def _cgroup_room() -> float | None:
    """Bytes the process's cgroup may still allocate (cgroup v2 ``memory.max - memory.current``,
    v1 ``limit - usage``), or None without a limit."""
    try:
        with open("/proc/self/cgroup") as fh:
            lines = fh.read().splitlines()
    except OSError:
        return None
    for line in lines:
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        if parts[0] == "0" and parts[1] == "":  # v2
            base = "/sys/fs/cgroup" + parts[2]
            limit, used = _read_number(base + "/memory.max"), _read_number(base + "/memory.current")
        elif "memory" in parts[1].split(","):  # v1
            base = "/sys/fs/cgroup/memory" + parts[2]
            limit = _read_number(base + "/memory.limit_in_bytes")
            used = _read_number(base + "/memory.usage_in_bytes")
            limit = None if limit is not None and limit >= 2**62 else limit  # "no limit" on v1
        else:
            continue
        if limit is not None and used is not None:
            return max(limit - used, 0.0)
    return None


def memory_limits() -> dict:
    """Bytes of memory the process can still allocate, by what bounds it: ``machine``
    (``MemAvailable`` of /proc/meminfo), ``address_space`` (the soft ``RLIMIT_AS``, ``ulimit -v``,
    less the process's ``VmSize`` and :data:`ADDRESS_SPACE_OVERHEAD`), ``cgroup`` (its memory
    limit less its usage); None where unknown or unlimited."""
    out = {"machine": _proc_field("/proc/meminfo", "MemAvailable"), "address_space": None, "cgroup": _cgroup_room()}
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft != resource.RLIM_INFINITY:
            used = _proc_field("/proc/self/status", "VmSize") or 0.0
            out["address_space"] = max(float(soft) - used - ADDRESS_SPACE_OVERHEAD, 0.0)
    except (ImportError, OSError, ValueError):
        pass
    return out


#: What each bound of :func:`memory_limits` is called in messages.
MEMORY_LIMIT_NAMES = {"machine": "the machine's available memory", "address_space": "the process's address-space "
                      "limit (ulimit -v)", "cgroup": "the memory limit of the process's cgroup (container)"}


def memory_available() -> float | None:
    """Bytes of memory available to new allocations: the smallest of :func:`memory_limits`, or None."""
    known = [v for v in memory_limits().values() if v is not None]
    return min(known) if known else None


def describe_memory() -> str:
    """``"N MB available (what bounds it)"`` for messages."""
    limits = {k: v for k, v in memory_limits().items() if v is not None}
    if not limits:
        return "the memory available is unknown"
    key = min(limits, key=lambda k: limits[k])
    return f"{limits[key] / 2**20:.0f} MB available ({MEMORY_LIMIT_NAMES[key]})"



#: Address space a job needs beyond what a started process has mapped (and the overhead), whatever
#: its size: the solver libraries loaded on first use (MKL for PARDISO: ~350 MB of mappings). Below
#: it a job cannot start.
START_RESERVE = 384 * 2**20


def start_room() -> str | None:
    """The message when the process's address-space or cgroup limit leaves less than
    :data:`START_RESERVE` to a job (None when there is room, or no such limit)."""
    limits = memory_limits()
    for key in ("address_space", "cgroup"):
        room = limits.get(key)
        if room is not None and room < START_RESERVE:
            return (f"out of memory before starting: {MEMORY_LIMIT_NAMES[key]} leaves {megabytes(room)}, a job "
                    f"needs at least {megabytes(START_RESERVE)} beyond the libraries already loaded (BLAS and solver "
                    "buffers); raise the limit")
    return None


#: Copies of an ``n x r`` basis a reduction holds at once (the basis, its orthogonalization, the
#: products with M and K, the solves' right-hand sides), in :func:`check_basis_memory`.
BASIS_COPIES = 4


def check_basis_memory(n: int, order: int, solver) -> None:
    """Refuse, before any work, a basis of ``order`` vectors of ``n`` equations that cannot fit:
    :data:`BASIS_COPIES` dense ``n x order`` arrays against :data:`MEMORY_FRACTION` of the memory
    ``solver`` may use (:meth:`~flexmor.linalg.context.SolverContext.memory_available`).

    Raises
    ------
    OutOfMemoryError
        Naming the memory needed and available, what bounds it, and the largest order that fits.
    """
    avail = solver.memory_available()
    need = BASIS_COPIES * 8.0 * n * order
    if avail is None or need <= MEMORY_FRACTION * avail:
        return
    fits = int(MEMORY_FRACTION * avail // (BASIS_COPIES * 8.0 * n))
    raise OutOfMemoryError(
        f"a basis of order {order} for {n} equations needs about {megabytes(need)} ({BASIS_COPIES} arrays of n x r "
        f"doubles), but only {megabytes(avail)} of memory are available{bound(avail)}; "
        + (f"order {fits} or less would fit" if fits >= 1 else "no order fits: a machine with more memory"),
        params=("order",))


def bound(available: float) -> str:
    """`` (what bounds it)`` when ``available`` is one of :func:`memory_limits`, else ``""``
    (a ``memory_limit`` given)."""
    for key, value in memory_limits().items():
        if value is not None and abs(value - available) <= 1e-6 * max(value, 1.0):
            return f" ({MEMORY_LIMIT_NAMES[key]})"
    return ""
