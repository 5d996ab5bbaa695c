"""A small OUTPUT4 writer for tests: binary (either byte order, 32/64-bit) and ASCII, dense or sparse.

Written from the format description (DMAP OUTPUT4): header record ``NCOL NROW FORM TYPE
NAME``, one record per non-zero column ``ICOL IROW NW values``, closing record ``NCOL+1``.
"""

from __future__ import annotations

import struct

import numpy as np


def _runs(col):
    """``(first row 1-based, values)`` of the contiguous non-zero runs of a column."""
    nz = np.flatnonzero(col)
    if nz.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(nz) > 1)
    starts = np.concatenate([[0], breaks + 1])
    ends = np.concatenate([breaks + 1, [nz.size]])
    return [(int(nz[a]) + 1, col[nz[a]:nz[b - 1] + 1]) for a, b in zip(starts, ends)]


def write_binary(path, mats, *, endian="<", bit64=False, sparse=False, bigmat=False, typ=2, form=None):
    ic = "q" if bit64 else "i"
    cplx = typ > 2
    single = typ in (1, 3) and not bit64
    vdt = np.dtype(endian + ("f4" if single else "f8"))
    wper = 1 if (single or bit64) else 2
    out = bytearray()

    def rec(body):
        out.extend(struct.pack(endian + "i", len(body)) + body + struct.pack(endian + "i", len(body)))

    def words(vals):
        v = np.asarray(vals)
        if cplx:
            v = np.column_stack([v.real, v.imag]).ravel()
        return v.astype(vdt).tobytes(), v.size * wper

    for name, A in mats.items():
        A = np.asarray(A)
        nrow, ncol = A.shape
        f = form or (6 if nrow == ncol and np.allclose(A, A.T) else 2 if nrow != ncol else 1)
        rec(struct.pack(endian + "4" + ic, ncol, -nrow if bigmat else nrow, f, typ)
            + name.ljust(16 if bit64 else 8).encode())
        for j in range(ncol):
            runs = _runs(A[:, j])
            if not runs:
                continue
            if not sparse:
                r0 = runs[0][0]
                r1 = runs[-1][0] + len(runs[-1][1]) - 1
                data, nw = words(A[r0 - 1:r1, j])
                rec(struct.pack(endian + "3" + ic, j + 1, r0, nw) + data)
                continue
            body, nw = b"", 0
            for r0, v in runs:
                data, L = words(v)
                if bigmat:
                    body += struct.pack(endian + "2" + ic, L + 1, r0)
                    nw += L + 2
                else:
                    body += struct.pack(endian + ic, (L + 1) * 65536 + r0)
                    nw += L + 1
                body += data
            rec(struct.pack(endian + "3" + ic, j + 1, 0, nw) + body)
        data, nw = words(np.ones(1))
        rec(struct.pack(endian + "3" + ic, ncol + 1, 1, nw) + data)
    with open(path, "wb") as fh:
        fh.write(bytes(out))


def write_ascii(path, mats, *, sparse=False, bigmat=False, per_line=3, width=23, form=2):
    lines = []

    def vals(v):
        v = [f"{x:{width}.{width - 7}E}" for x in v]
        return ["".join(v[k:k + per_line]) for k in range(0, len(v), per_line)]

    for name, A in mats.items():
        A = np.asarray(A, float)
        nrow, ncol = A.shape
        head = f"{ncol:8d}{-nrow if bigmat else nrow:8d}{form:8d}{2:8d}{name:<8}"
        lines.append(f"{head}1P,{per_line}E{width}.{width - 7}")
        for j in range(ncol):
            runs = _runs(A[:, j])
            if not runs:
                continue
            if not sparse:
                r0, r1 = runs[0][0], runs[-1][0] + len(runs[-1][1]) - 1
                lines.append(f"{j + 1:8d}{r0:8d}{r1 - r0 + 1:8d}")
                lines += vals(A[r0 - 1:r1, j])
                continue
            nw = sum(2 * len(v) + (2 if bigmat else 1) for _, v in runs)
            lines.append(f"{j + 1:8d}{0:8d}{nw:8d}")
            for r0, v in runs:
                L = 2 * len(v)
                lines.append(f"{L + 1:8d}{r0:8d}" if bigmat else f"{(L + 1) * 65536 + r0:12d}")
                lines += vals(v)
        lines.append(f"{ncol + 1:8d}{1:8d}{1:8d}")
        lines += vals([1.0])
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")
