"""The normal equations of the block-banded solve, in LAPACK's lower band storage.

:class:`ActiveNormalEquations` is what :func:`pinrecon.solver.solve` uses. It assembles
``H = J^T J`` and ``g = J^T r`` over the **active** tangent entries only (entries held at
their start, e.g. the twist of a hand no tracked point sees, are not unknowns at all, so
the band shrinks from ``2 nv + 5`` to ``2 na + 5``: the human's 42 tangent entries with
COCO-17 give 32 active ones, a factorisation 2.2 times cheaper), straight into a
Fortran-ordered band buffer allocated once per solve (LAPACK's ``dpbtrf`` factors it in
place: a C-ordered buffer is silently copied by the wrapper, 2-3 times the cost).

The structure is worked out once per solve (:class:`_BlockPlan`, "symbolic" work): for
every row block and pair of its frames, which active columns it covers, at which frame
distance, and which frames it writes to (runs of consecutive frames become slices).
Each iteration then computes the small products ``J_i^T J_j`` and adds them through
two views of the band buffer ``ab`` (``ab[k, j] = H[j + k, j]``):

* ``abv[t, c, k] = H[t na + c + k, t na + c]`` (a reshape), for diagonal blocks and
  blocks between frames (``k = d na + a - c``);
* ``S[t, c, a] = H[t na + a, t na + c]`` (a strided view, valid for ``a >= c``), so a
  frame's dense block ``B`` goes in as ``S[t] += triu(B)``; the entries ``a < c`` of
  this view alias other band entries and receive exact zeros (the view never maps two
  of its own entries to one address as long as ``kd >= na``, which is enforced).

:class:`BandedNormalEquations` is the earlier assembler over all ``nv`` entries (frozen
ones carried with unit diagonals), kept as the reference the tests compare against.
:class:`ArrowheadFactor` factors the band with a border of global unknowns (Schur
complement, ``docs/globals.md``).
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import as_strided
from scipy.linalg import LinAlgError, cho_factor, cho_solve
from scipy.linalg.blas import dtrmm as _trmm
from scipy.linalg.lapack import dpbtrf as _pbtrf
from scipy.linalg.lapack import dpbtrs as _pbtrs
from scipy.linalg.lapack import dtbtrs as _tbtrs

__all__ = ["ActiveNormalEquations", "ArrowheadFactor", "BandedNormalEquations", "forward_solve", "schur_complement"]

#: frames written as slices when a row block's frames form at most this many runs
_MAX_RUNS = 16

#: bytes of band factor per chunk of :func:`forward_solve` (stays in the core's cache
#: while every right-hand side passes through it)
_CHUNK_BYTES = 2 << 20


def forward_solve(c: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``L^-1 B`` for the lower band factor ``c`` ((kd + 1, n), Fortran-ordered, as
    ``dpbtrf`` leaves it) and a dense ``B`` (n, k).

    The same numbers as ``dtbtrs(c, B)``, which streams the whole factor once per column
    of ``B``; here the factor is cut into chunks of rows of about ``_CHUNK_BYTES`` that
    every column passes through while they are in cache. Chunk ``[r0, r1)`` is the band
    slice ``c[:, r0:r1]`` (its own diagonal block, a contiguous band matrix: no copy), and
    the previous chunk's last ``kd`` solutions enter its first ``kd`` right-hand sides
    through the factor's ``kd x kd`` upper-triangular coupling block
    ``L[r0 : r0 + kd, r0 - kd : r0]``, read in place (``L[i, j]`` is the ``i + j kd``-th
    double of the band storage, so the block is a Fortran matrix with leading dimension
    ``kd``; its strictly lower part aliases other entries and is never read by ``dtrmm``).
    About a third faster than ``dtbtrs`` for ten columns of the 1000-frame human problem.
    Raises :class:`scipy.linalg.LinAlgError` on a zero pivot."""
    kd, n = c.shape[0] - 1, c.shape[1]
    B = np.asarray(B, float)
    rows = max(4 * max(kd, 1), _CHUNK_BYTES // (8 * (kd + 1)))
    if n <= rows or kd == 0 or B.shape[1] < 2 or not c.flags.f_contiguous:
        Z, info = _tbtrs(c, B, uplo="L", trans="N")
        if info != 0:
            raise LinAlgError(f"banded triangular solve failed (info {info})")
        return Z
    flat = c.reshape(-1, order="F")
    Z = np.empty(B.shape, order="F")
    for r0 in range(0, n, rows):
        r1 = min(n, r0 + rows)
        rhs = np.array(B[r0:r1], order="F")
        if r0:
            U = as_strided(flat[r0 + (r0 - kd) * kd :], shape=(kd, kd), strides=(8, 8 * kd))
            m = min(kd, r1 - r0)
            rhs[:m] -= _trmm(1.0, U, np.asfortranarray(Z[r0 - kd : r0]), lower=0)[:m]
        z, info = _tbtrs(c[:, r0:r1], rhs, uplo="L", trans="N")
        if info != 0:
            raise LinAlgError(f"banded triangular solve failed (info {info + r0 if info > 0 else info})")
        Z[r0:r1] = z
    return Z


class _Frames:
    """Adds per-row-group values into ``target[frames, *rest]``: slices over runs of
    consecutive frames, else one fancy-indexed add (``np.add.at`` when frames repeat)."""

    __slots__ = ("idx", "runs", "unique")

    def __init__(self, idx):
        idx = np.asarray(idx, dtype=np.int64)
        self.idx = idx
        self.unique = len(np.unique(idx)) == len(idx)
        self.runs = None
        if len(idx) and self.unique and np.all(np.diff(idx) > 0):
            br = np.flatnonzero(np.diff(idx) != 1) + 1
            starts, ends = np.r_[0, br], np.r_[br, len(idx)]
            if len(starts) <= _MAX_RUNS:
                self.runs = [(int(idx[a]), int(idx[a]) + int(b - a), int(a)) for a, b in zip(starts, ends)]

    def add(self, target, rest: tuple, values: np.ndarray) -> None:
        if not len(self.idx):
            return
        if self.runs is not None:
            one = len(self.runs) == 1
            for a, b, o in self.runs:
                target[(slice(a, b),) + rest] += values if one else values[o : o + b - a]
            return
        nd = max((np.ndim(x) for x in rest), default=0)
        key = (self.idx.reshape((-1,) + (1,) * nd),) + rest
        if self.unique:
            target[key] += values
        else:
            np.add.at(target, key, values)


def _index(cc: np.ndarray):
    """A slice when the columns are consecutive (plain strided views), else the array."""
    if len(cc) and cc[-1] - cc[0] == len(cc) - 1 and np.all(np.diff(cc) == 1):
        return slice(int(cc[0]), int(cc[-1]) + 1)
    return cc


class _BlockPlan:
    """Where one row block's products go (see the module docstring), worked out once."""

    def __init__(self, b, cmap: np.ndarray, na: int):
        cols = np.asarray(b.cols, dtype=int)
        cc_all = cmap[cols] if len(cols) else np.zeros(0, int)
        keep = np.flatnonzero(cc_all >= 0)
        self.keep = None if len(keep) == len(cols) else keep
        cc = cc_all[keep]
        self.frames, self.cols, self.diagonal = b.frames, cols, bool(b.diagonal)
        self.empty = b.frames.shape[0] == 0 or len(cc) == 0 or b.r.shape[1] == 0
        self.cc = cc
        # which within-frame entries B[x, y] -> H[cc[y], cc[x]] are band entries (cc[y] >= cc[x])
        self.upper = (cc[None, :] >= cc[:, None]).astype(float)
        ci = _index(cc)
        contiguous = isinstance(ci, slice)
        F = np.asarray(b.frames)
        s = F.shape[1]
        self.grad = [(_Frames(F[:, i]), (ci,)) for i in range(s)]
        self.pairs = []
        self.kd = 0
        if self.empty:
            return
        self.c = len(cc)
        for i in range(s):
            for j in range(i + 1):
                dist = F[:, i] - F[:, j]
                if np.any(dist < 0):
                    raise ValueError(f"row kind {b.name!r}: frames must be increasing within a row group")
                ds = np.unique(dist)
                for d in ds:
                    d = int(d)
                    sel = None if len(ds) == 1 else dist == d
                    fr = _Frames(F[:, j] if sel is None else F[sel, j])
                    if self.diagonal:  # H[(t + d) na + c, t na + c]: summed per distance d first
                        kind, rest = "diag", (ci,)
                        self.kd = max(self.kd, d * na)
                    elif d == 0:  # the frame view S[t, cc, cc] (its entries a >= c)
                        kind, rest = "frame", (ci, ci) if contiguous else (cc[:, None], cc[None, :])
                    elif contiguous:  # S_d[t, c, a] = H[(t + d) na + a, t na + c] gets B^T
                        kind, rest = d, (ci, ci)
                        self.kd = max(self.kd, d * na + len(cc) - 1)
                    else:  # B[n, x, y]: row cc[x] of frame t + d, column cc[y] of frame t
                        k = d * na + cc[:, None] - cc[None, :]
                        kind, rest = "abv", (np.broadcast_to(cc[None, :], k.shape), k)
                        self.kd = max(self.kd, int(k.max()))
                    self.pairs.append((i, j, d, sel, fr, kind, rest))

    def matches(self, b) -> bool:
        """Whether block ``b`` has this plan's structure (a row kind keeps its frames and
        columns within a solve; a change of shape means a new structure)."""
        return bool(b.diagonal) == self.diagonal and b.frames.shape == self.frames.shape and len(b.cols) == len(self.cols)


class ActiveNormalEquations:
    """``H = J^T J`` over the active tangent entries, in a band buffer reused by every
    iteration of one solve (see the module docstring).

    Parameters
    ----------
    T, nv : frames and tangent size per frame.
    blocks : the row blocks (their structure; the values are read by :meth:`assemble`).
    active : (nv,) bool, the entries that are unknowns (default all).

    Attributes
    ----------
    na, n : active entries per frame, unknowns ``T na``; ``kd`` the half-bandwidth.
    ab : (kd + 1, n) Fortran-ordered lower band storage of the last assembled ``H``
        (overwritten by a factorisation).
    """

    def __init__(self, T: int, nv: int, blocks, active=None):
        self.T, self.nv = int(T), int(nv)
        act = np.arange(nv) if active is None else np.flatnonzero(np.asarray(active, bool))
        self.act = act
        self.na = len(act)
        self.n = self.T * self.na
        self.cmap = np.full(nv, -1, dtype=int)
        self.cmap[act] = np.arange(self.na)
        self.ab = None
        self._plan(blocks)

    def _plan(self, blocks):
        self.plans = [_BlockPlan(b, self.cmap, self.na) for b in blocks]
        kd = max([self.na] + [p.kd for p in self.plans])  # kd >= na keeps the frame view S one-to-one
        if self.ab is None or kd != self.kd:
            self.kd = kd
            self.ab = np.zeros((kd + 1, self.n), order="F")
        T, na = self.T, self.na
        self.abv = self.ab.T.reshape(T, na, kd + 1)  # abv[t, c, k] = H[t na + c + k, t na + c]
        self._views, self._buffers = {}, {}

    def _view(self, d: int):
        """``S_d[t, c, a] = H[(t + d) na + a, t na + c]`` (t < T - d), a strided view of the
        band buffer, one-to-one because ``kd >= na``; entries outside the band alias other
        band entries and may only receive zeros (d = 0: ``a < c``)."""
        if d not in self._views:
            na, kd, st = self.na, self.kd, self.ab.itemsize
            flat = self.ab.ravel(order="F")[d * na :]
            self._views[d] = as_strided(flat, shape=(max(self.T - d, 0), na, na),
                                        strides=(na * (kd + 1) * st, kd * st, st))
        return self._views[d]

    def expand(self, dx: np.ndarray) -> np.ndarray:
        """(T, nv) from active entries (n,): zeros at the held entries."""
        out = np.zeros((self.T, self.nv))
        out[:, self.act] = dx.reshape(self.T, self.na)
        return out

    def diagonal(self) -> np.ndarray:
        return self.ab[0].copy()

    def assemble(self, blocks, n_g: int = 0):
        """Fill ``ab`` with ``H`` (undamped) and return ``g = J^T r`` (n,) and, with
        ``n_g`` globals, the border ``(B (n, n_g) Fortran-ordered, C, g_g)``.

        The first within-frame product covering whole frames (the 2D measurements) is
        written by ``matmul`` straight into the frame view ``S`` (its entries ``a < c``,
        which alias other band entries, are zeroed with the rest of the band right after,
        so no separate zeroing pass over the whole band); the other products are added
        into the band views (``S[t] += triu(B)``)."""
        if len(blocks) != len(self.plans) or not all(p.matches(b) for p, b in zip(self.plans, blocks)):
            self._plan(blocks)  # the rows changed their structure: plan again
        T, na = self.T, self.na
        if T == 1:  # one frame (a start's pose fits): a small dense H, few NumPy calls
            g = self._assemble_one_frame(blocks)
            return g, (self._border(blocks, n_g) if n_g else None)
        g = np.zeros((T, na))
        S, diag = self._view(0), {}
        written = False  # whether the band holds anything yet (it is zeroed before the first write)
        for b, p in zip(blocks, self.plans):
            if p.empty:
                continue
            J = b.J if p.keep is None else np.take(b.J, p.keep, axis=-1)
            r = b.r if p.keep is None or not p.diagonal else b.r[:, p.keep]
            for i, (fr, rest) in enumerate(p.grad):
                Ji = J[:, i]
                fr.add(g, rest, Ji * r if p.diagonal else np.matmul(r[:, None, :], Ji)[:, 0])
            if p.diagonal:
                for i, j, d, sel, fr, kind, rest in p.pairs:
                    Ji, Jj = (J[:, i], J[:, j]) if sel is None else (J[sel, i], J[sel, j])
                    if d not in diag:
                        diag[d] = self._buffer(("diag", d), (T, na))
                    fr.add(diag[d], rest, Ji * Jj if i == j or d else 2.0 * (Ji * Jj))
                continue
            s, c = J.shape[1], p.c
            first = p.pairs[0] if len(p.pairs) == 1 else None
            if not written and first is not None and first[5] == "frame" and first[4].runs is not None \
                    and isinstance(first[6][0], slice):
                # the first within-frame product (the 2D measurements): written straight into the
                # band's frame view S (its entries a < c land on other band entries)
                cs, runs = first[6], first[4].runs
                full = cs[0] == slice(0, na) and sum(b_ - a for a, b_, _ in runs) == T
                if not full:
                    self.ab.fill(0.0)
                Jt = J[:, 0].transpose(0, 2, 1)
                c0 = cs[0].start
                for a, b_, o in runs:
                    np.matmul(Jt[o : o + b_ - a], J[o : o + b_ - a, 0], out=S[(slice(a, b_),) + cs])
                    if not full:  # the entries a < c: back to zero
                        for x in range(1, c):
                            S[a:b_, c0 + x, c0 : c0 + x] = 0.0
                if full:  # every frame's block written: zero the rest of the band (rows >= na - x of column x)
                    for x in range(na):
                        self.abv[:, x, na - x :] = 0.0
                written = True
                continue
            if not written:
                self.ab.fill(0.0)
            written = True
            # every pair's J_i^T J_j at once: JJ[n, i c + x, j c + y] = (J_i^T J_j)[x, y]
            Jcat = J.transpose(0, 2, 1, 3).reshape(J.shape[0], J.shape[2], s * c) if s > 1 else J[:, 0]
            JJ = np.matmul(Jcat.transpose(0, 2, 1), Jcat)
            for i, j, d, sel, fr, kind, rest in p.pairs:
                B = JJ[:, i * c : (i + 1) * c, j * c : (j + 1) * c]  # J_i^T J_j
                if sel is not None:
                    B = B[sel]
                if kind == "frame":  # S[t, c, a] = H[t na + a, t na + c] takes the entries a >= c
                    if i != j:  # the same frame twice in one row group: both halves
                        B = B + B.transpose(0, 2, 1)
                    fr.add(S, rest, B * p.upper)  # entries a < c alias other band entries: + 0
                elif kind == "abv":
                    fr.add(self.abv, rest, B)
                else:  # S_d[t] takes B^T
                    fr.add(self._view(kind), rest, B.transpose(0, 2, 1))
        if not written:
            self.ab.fill(0.0)
        # the band's entries are far apart in memory (kd + 1 doubles): contiguous sums first,
        # then one pass into the band per kind of entry
        for d, acc in diag.items():
            self.abv[: T - d, :, d * na] += acc[: T - d]
        border = self._border(blocks, n_g) if n_g else None
        return g.reshape(-1), border

    def _assemble_one_frame(self, blocks) -> np.ndarray:
        na = self.na
        H = np.zeros((na, na))
        g = np.zeros(na)
        for b, p in zip(blocks, self.plans):
            if p.empty:
                continue
            cc = p.cc
            J = b.J.sum(axis=1) if b.J.shape[1] > 1 else b.J[:, 0]  # every frame of every row group is 0
            if p.diagonal:  # J (N, c)
                Jd, rd = (J, b.r) if p.keep is None else (J[:, p.keep], b.r[:, p.keep])
                H[cc, cc] += np.einsum("nc,nc->c", Jd, Jd)
                g[cc] += np.einsum("nc,nc->c", Jd, rd)
            else:  # J (N, m, c)
                Jb = J if p.keep is None else J[..., p.keep]
                Jf = Jb.reshape(-1, Jb.shape[-1])
                H[np.ix_(cc, cc)] += Jf.T @ Jf
                g[cc] += b.r.reshape(-1) @ Jf
        self.ab.fill(0.0)
        self._view(0)[0] += np.triu(H)  # S[0, c, a] = H[a, c] for a >= c (symmetric H)
        return g

    def _buffer(self, key, shape) -> np.ndarray:
        """A zeroed scratch array, allocated once per solve (no fresh pages every iteration)."""
        buf = self._buffers.get(key)
        if buf is None or buf.shape != shape:
            buf = self._buffers[key] = np.zeros(shape)
        else:
            buf.fill(0.0)
        return buf

    def _border(self, blocks, n_g):
        """``B = J_x^T J_g`` (n, n_g), ``C = J_g^T J_g``, ``g_g = J_g^T r``."""
        T, na = self.T, self.na
        B = np.zeros((n_g, T, na)).transpose(1, 2, 0)  # (T, na, n_g), column-major as (n, n_g)
        C = np.zeros((n_g, n_g))
        gg = np.zeros(n_g)
        fresh = True  # nothing added into B yet: the first product over runs of frames is written straight in
        for b, p in zip(blocks, self.plans):
            if b.Jg is None or b.r.size == 0:
                continue
            gc = np.asarray(b.gcols, dtype=int)
            Jflat = b.Jg.reshape(-1, len(gc))
            C[np.ix_(gc, gc)] += Jflat.T @ Jflat
            gg[gc] += Jflat.T @ b.r.reshape(-1)
            if p.empty:
                continue
            J = b.J if p.keep is None else np.take(b.J, p.keep, axis=-1)
            ci, gi = _index(p.cc), _index(gc)
            # slices where the columns are consecutive (strided adds, no gather and scatter)
            rest = (ci, gi) if isinstance(ci, slice) and isinstance(gi, slice) else (p.cc[:, None], gc[None, :])
            for i, (fr, _) in enumerate(p.grad):
                Ji = J[:, i]
                if fresh and not p.diagonal and fr.runs is not None and isinstance(rest[0], slice):
                    Jt = Ji.transpose(0, 2, 1)
                    for a, b_, o in fr.runs:  # disjoint runs of zeros: matmul writes there (no temporary, no add)
                        np.matmul(Jt[o : o + b_ - a], b.Jg[o : o + b_ - a], out=B[(slice(a, b_),) + rest])
                else:
                    Bi = Ji[:, :, None] * b.Jg if p.diagonal else np.matmul(Ji.transpose(0, 2, 1), b.Jg)  # (N, c, g)
                    fr.add(B, rest, Bi)
                fresh = False
        return B.reshape(T * na, n_g), C, gg

    def gradient(self, blocks, residuals) -> np.ndarray:
        """``J^T r`` (n,) for the blocks' Jacobians and other residuals (list of (N, m))."""
        g = np.zeros((self.T, self.na))
        for b, p, r in zip(blocks, self.plans, residuals):
            if p.empty:
                continue
            J = b.J if p.keep is None else np.take(b.J, p.keep, axis=-1)
            if p.diagonal and p.keep is not None:
                r = r[:, p.keep]
            for i, (fr, rest) in enumerate(p.grad):
                Ji = J[:, i]
                fr.add(g, rest, Ji * r if p.diagonal else np.matmul(r[:, None, :], Ji)[:, 0])
        return g.reshape(-1)


class BandedNormalEquations:
    """``H = J^T J``, ``g = J^T r`` assembled from row blocks into LAPACK lower band storage.

    Blocks of H are kept per frame distance d: ``D[0]`` (T, nv, nv) dense within-frame
    blocks, and for d >= 1 only the structurally non-zero entries of block (t+d, t),
    ``Dd[d]`` (T-d, nnz_d). ``kd`` is the scalar half-bandwidth implied by the structure.
    """

    def __init__(self, T: int, nv: int, blocks):
        self.T, self.nv = T, nv
        masks: dict[int, np.ndarray] = {}
        for b in blocks:
            s = b.frames.shape[1]
            cols = np.asarray(b.cols)
            for i in range(s):
                for j in range(i):
                    dist = np.unique(b.frames[:, i] - b.frames[:, j])
                    if np.any(dist < 0):
                        raise ValueError(f"row kind {b.name!r}: frames must be increasing within a row group")
                    for d in dist:
                        d = int(d)
                        if d == 0:
                            continue
                        m = masks.setdefault(d, np.zeros((nv, nv), dtype=bool))
                        if b.diagonal:
                            m[cols, cols] = True
                        else:
                            m[np.ix_(cols, cols)] = True
        kd = nv - 1
        self.pos: dict[int, np.ndarray] = {}
        self.entries: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        for d, m in masks.items():
            a, c = np.nonzero(m)  # block (t+d, t): row a of frame t+d, col c of frame t
            kd = max(kd, int(np.max(d * nv + a - c)))
            pos = np.full((nv, nv), -1, dtype=np.int64)
            pos[a, c] = np.arange(len(a))
            self.pos[d] = pos
            self.entries[d] = (a, c)
        self.kd = kd
        self.distances = sorted(masks)

    @staticmethod
    def _scatter(target, idx_frames, values, idx_rest):
        """target[idx_frames, *idx_rest] += values, safe for repeated frames."""
        n = len(idx_frames)
        step = np.diff(idx_frames)
        increasing = bool(np.all(step > 0))  # row groups list frames in order: no repeats
        if n and not idx_rest and increasing and idx_frames[-1] - idx_frames[0] == n - 1:
            target[idx_frames[0] : idx_frames[0] + n] += values  # contiguous frames: a slice
            return
        nd = max((np.ndim(a) for a in idx_rest), default=1)
        fr = idx_frames.reshape((-1,) + (1,) * (nd - 1)) if idx_rest else idx_frames
        if increasing or len(np.unique(idx_frames)) == n:
            target[(fr,) + idx_rest] += values
        else:
            np.add.at(target, (fr,) + idx_rest, values)

    def assemble(self, blocks):
        T, nv = self.T, self.nv
        D0 = np.zeros((T, nv, nv))
        Dd = {d: np.zeros((T - d, len(self.entries[d][0]))) for d in self.distances}
        g = np.zeros((T, nv))
        for b in blocks:
            F, r, J, cols = b.frames, b.r, b.J, np.asarray(b.cols)
            if F.shape[0] == 0 or len(cols) == 0 or r.shape[1] == 0:
                continue
            full = len(cols) == nv and np.array_equal(cols, np.arange(nv))
            s = F.shape[1]
            for i in range(s):
                fi = F[:, i]
                if b.diagonal:
                    self._scatter(g, fi, J[:, i] * r, (cols[None, :],))
                else:
                    gi = np.einsum("nmc,nm->nc", J[:, i], r)
                    if full:
                        self._scatter(g, fi, gi, ())
                    else:
                        self._scatter(g, fi, gi, (cols[None, :],))
                for j in range(i + 1):
                    fj = F[:, j]
                    dist = fi - fj
                    if b.diagonal:
                        B = J[:, i] * J[:, j]  # (N, c)
                    else:
                        B = np.matmul(J[:, i].transpose(0, 2, 1), J[:, j])  # (N, c, c)
                    ds = (dist[0],) if (len(dist) and np.all(dist == dist[0])) else np.unique(dist)
                    for d in ds:
                        sel = dist == d
                        Bs = B if sel.all() else B[sel]
                        rows_f, cols_f = fi[sel], fj[sel]
                        if d == 0:
                            if i != j:  # same frame twice in one row group: add both halves
                                Bs = Bs + (Bs if b.diagonal else Bs.transpose(0, 2, 1))
                            if b.diagonal:
                                self._scatter(D0, rows_f, Bs, (cols[None, :], cols[None, :]))
                            elif full:
                                self._scatter(D0, rows_f, Bs, ())
                            else:
                                self._scatter(D0, rows_f, Bs, (cols[None, :, None], cols[None, None, :]))
                        else:
                            pos = self.pos[int(d)]
                            if b.diagonal:
                                k = pos[cols, cols]
                                self._scatter(Dd[int(d)], cols_f, Bs, (k[None, :],))
                            else:
                                k = pos[np.ix_(cols, cols)]
                                self._scatter(Dd[int(d)], cols_f, Bs, (k[None, :, :],))
        return D0, Dd, g.reshape(-1)

    def assemble_globals(self, blocks, n_g: int):
        """The border of the arrowhead: ``B = J_x^T J_g`` (T nv, n_g), ``C = J_g^T J_g``
        (n_g, n_g) and ``g_g = J_g^T r`` (n_g,), from the blocks' ``Jg``/``gcols``."""
        T, nv = self.T, self.nv
        B = np.zeros((n_g, T, nv)).transpose(1, 2, 0)  # (T, nv, n_g), column-major as (T nv, n_g)
        C = np.zeros((n_g, n_g))
        gg = np.zeros(n_g)
        for b in blocks:
            if b.Jg is None or b.r.size == 0:
                continue
            gc = np.asarray(b.gcols, dtype=int)
            Jg = b.Jg
            Jflat = Jg.reshape(-1, len(gc))
            C[np.ix_(gc, gc)] += Jflat.T @ Jflat
            gg[gc] += Jflat.T @ b.r.reshape(-1)
            cols = np.asarray(b.cols)
            if len(cols) == 0:
                continue
            all_g = len(gc) == n_g and np.array_equal(gc, np.arange(n_g))
            full = all_g and len(cols) == nv and np.array_equal(cols, np.arange(nv))
            for i in range(b.frames.shape[1]):
                if b.diagonal:
                    Bi = b.J[:, i][:, :, None] * Jg  # (N, c, g)
                else:
                    Bi = np.matmul(b.J[:, i].transpose(0, 2, 1), Jg)  # (N, c, g)
                fi = b.frames[:, i]
                if full:
                    self._scatter(B, fi, Bi, ())
                else:
                    self._scatter(B, fi, Bi, (cols[None, :, None], gc[None, None, :]))
        return B.reshape(T * nv, n_g), C, gg

    def gradient(self, blocks, residuals) -> np.ndarray:
        """J^T r for the blocks' Jacobians and other residuals ``residuals`` (list of (N, m))."""
        g = np.zeros((self.T, self.nv))
        for b, r in zip(blocks, residuals):
            cols = np.asarray(b.cols)
            if b.frames.shape[0] == 0 or len(cols) == 0 or r.shape[1] == 0:
                continue
            for i in range(b.frames.shape[1]):
                gi = b.J[:, i] * r if b.diagonal else np.einsum("nmc,nm->nc", b.J[:, i], r)
                self._scatter(g, b.frames[:, i], gi, (cols[None, :],))
        return g.reshape(-1)

    def band(self, D0, Dd, out: np.ndarray | None = None) -> np.ndarray:
        """LAPACK lower band storage ``ab[i - j, j] = H[i, j]`` (i >= j), into ``out`` when
        given (a buffer reused across iterations: no fresh 30 MB page faults each time)."""
        T, nv, kd = self.T, self.nv, self.kd
        if out is None:
            ab = np.zeros((kd + 1, T * nv))
        else:
            ab = out
            ab.fill(0.0)
        # within-frame blocks, one sub-diagonal k at a time: ab[k, t nv + c] = D0[t, c + k, c]
        for k in range(nv):
            ab[k].reshape(T, nv)[:, : nv - k] = np.diagonal(D0, -k, axis1=1, axis2=2)
        for d in self.distances:
            a, c = self.entries[d]
            base_d = (np.arange(T - d) * nv)[:, None]
            ab[(d * nv + a - c)[None, :], base_d + c[None, :]] = Dd[d]
        return ab


def schur_complement(c: np.ndarray, B: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(Z, S)`` of the arrowhead ``[[A, B], [B^T, C]]`` given ``A = L L^T`` as the lower
    band factor ``c``: ``Z = L^-1 B`` (one banded forward substitution per column of ``B``
    that couples to the motion; a zero column, e.g. a held global, stays zero) and the
    Schur complement ``S = C - Z^T Z`` (n_g, n_g), not factored (it may be only semi-definite
    when some rows are left out: :func:`pinrecon.solver.globals_information`)."""
    n_g = B.shape[1]
    coupled = np.flatnonzero(np.abs(B).max(axis=0) > 0) if B.shape[0] else np.zeros(0, int)
    if len(coupled) == n_g:
        Z = forward_solve(c, B)
    else:
        Z = np.zeros(B.shape, order="F")
        if len(coupled):
            Z[:, coupled] = forward_solve(c, B[:, coupled])
    return Z, C - Z.T @ Z


class ArrowheadFactor:
    """Factor ``[[A, B], [B^T, C]]`` (A banded in LAPACK lower storage, already damped;
    B (N, n_g) dense; C (n_g, n_g), already damped) once, then solve for any right-hand
    side through the Schur complement (see the module docstring).

    ``ab`` is overwritten by its Cholesky factor. Raises :class:`scipy.linalg.LinAlgError`
    when A or the Schur complement is not positive definite. Without a border (``B`` is
    ``None`` or has no column) this is the plain banded solve ``dpbtrs``.
    """

    def __init__(self, ab: np.ndarray, B: np.ndarray | None = None, C: np.ndarray | None = None):
        c, info = _pbtrf(ab, lower=1, overwrite_ab=1)  # in place: no copy of the band
        if info != 0:
            raise LinAlgError(f"banded Cholesky failed (info {info})")
        self.c = c
        self.n_g = 0 if B is None else B.shape[1]
        self.Z = self.S = None
        if self.n_g:
            Z, S = schur_complement(c, B, C)
            self.Z, self.S = Z, cho_factor(S, lower=True, check_finite=False)

    def solve(self, b_x: np.ndarray, b_g: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """``(x, y)`` with ``A x + B y = b_x`` and ``B^T x + C y = b_g``."""
        if not self.n_g:
            x, info = _pbtrs(self.c, b_x, lower=1)
            if info != 0:
                raise LinAlgError(f"banded solve failed (info {info})")
            return x, (None if b_g is None else np.zeros(0))
        z, info = _tbtrs(self.c, b_x[:, None], uplo="L", trans="N")
        z = z[:, 0]
        y = cho_solve(self.S, b_g - self.Z.T @ z, check_finite=False)
        x, info2 = _tbtrs(self.c, (z - self.Z @ y)[:, None], uplo="L", trans="T")
        if info or info2:
            raise LinAlgError("banded triangular solve failed")
        return x[:, 0], y
