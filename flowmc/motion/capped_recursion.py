"""The recursion y_k = min(c_k, min_i(a_ik y_{k+1} + b_ik)), solved exactly in numpy, for the time law's passes.

A pass of the time law (flowmc.motion.timelaw) carries the largest speed^2 a node may have from one node to
the next: at most its cap, and at most what one interval's budget allows from the next node's. With each
axis's budget linear in the speeds at the interval's ends, that allowance is an affine map per axis, and the
pass is this recursion. It is sequential; numpy runs it block by block instead:

1. With one map per step (the axis that binds at a guess of y), a step is y -> min(c, a y + b), and any
   chain of such steps is again of that form (min(C, A y + B)), so each block of ``_BLOCK`` steps is
   composed into one map, all blocks at once (one numpy row per step of every block), the blocks' maps are
   chained the same way (recursively) and each block is then run from its input. One map per step drops
   the other axes' limits, so this is an upper bound of the solution.
2. Every block is run again from those inputs with every axis's map (exact, given its input), and each
   block's input is lowered to what the block after it now gives; the binding axes are taken again at the
   new values, and step 1's bound of them kept where lower. Inputs only fall, and stop within rounding once
   every block agrees with the next (two to four rounds on the benchmark programs); after the first round
   only blocks whose input fell are run again (3D_Chips: 61, then 3 of 3,900 blocks backward).
"""

from __future__ import annotations

import numpy as np

from flowmc.motion.ranges import ranks

__all__ = ["descend", "descend_again"]

_BLOCK = 48  # steps per block: numpy then works on rows of n / 48 values (about 4,000 on 3D_Chips' grid)
_SETTLED = 1e-13  # relative: block inputs that fall less than this are settled (rounding of the composed maps)
_ROUNDS = 64  # a bound only: every round lowers an input, and rounding stops it far sooner
_GATHER = 128  # blocks ``_blocks`` lays out together (128 blocks of 9 maps: 440 kB)
_SHORT = 1024  # a single map's chain this short runs step by step in Python: faster than two sweeps of blocks
_REACH = 256  # nodes before a changed cap that ``descend_again`` first solves again (times 4 each time it falls short)
_MET = 1e-12  # relative: a value solved again this close to the old one has met it (``descend``'s own rounding: 1e-13)


def descend(cap: np.ndarray, a: list[np.ndarray], b: list[np.ndarray], guess: np.ndarray | None = None) -> np.ndarray:
    """The y with y_n = cap_n and y_k = min(cap_k, min_i(a[i]_k y_{k+1} + b[i]_k)) for k = n-1 .. 0.

    ``cap`` (n + 1,), each a[i] and b[i] (n,), every a > 0 (b may be inf: no limit from that map);
    ``guess``: an upper bound of the solution near it (n + 1,), where the binding axes are first taken (default: cap)."""
    n = len(cap) - 1
    end = float(cap[n])
    if len(a) == 1:
        return _then(_chain(cap[:n], a[0], b[0], end), end)
    if n <= 2 * _BLOCK:
        return _sequential(cap, a, b)
    c_blk = _blocks(cap[:n], np.inf)
    a_blk, b_blk = _blocks(a, 1.0), _blocks(b, 0.0)
    at = c_blk if guess is None else _blocks(guess[:n], np.inf)
    x_in = _then(at[0, 1:], end)  # the value after each block's last step: the next block's first
    maps = _composed(c_blk, *_chosen(a_blk, b_blk, np.vstack([at[1:], x_in])))
    y_blk, picks = np.empty_like(c_blk), np.empty(c_blk.shape, dtype=np.intp)
    ran = None
    for _ in range(_ROUNDS):
        first = _chain(maps[0], maps[1], maps[2], end)
        x_in = np.minimum(x_in, _then(first[1:], end))  # both are upper bounds of the solution
        # a block run again from the same input gives the same values and map: only the others are
        again = slice(None) if ran is None else np.flatnonzero(x_in != ran)
        c_part, a_part, b_part = c_blk[:, again], a_blk[:, again], b_blk[:, again]
        y_blk[:, again], picks[:, again] = _run(c_part, a_part, b_part, x_in[again])
        ran = x_in
        new_in = _then(y_blk[0, 1:], end)  # what each block's input now is: the next block's first value
        settled = not np.any(new_in < x_in * (1.0 - _SETTLED))
        x_in = new_in
        if settled:
            break
        for whole, part in zip(maps, _composed(c_part, *_picked(a_part, b_part, picks[:, again]))):
            whole[again] = part
    return _then(y_blk.T.reshape(-1)[:n], end)


def descend_again(cap: np.ndarray, old_cap: np.ndarray, old: np.ndarray, a: list[np.ndarray], b: list[np.ndarray]) -> np.ndarray:
    """``descend(cap, a, b)`` given ``old`` = ``descend(old_cap, a, b)``: solved again only about the nodes whose cap
    changed (the time law's caps lowered about a few samples over amax: 3D_Chips 786 of 273,226 nodes).

    y_k depends only on the caps from k on, so past a change's node the old values hold; before it they differ
    back to the first node whose value meets the old one again, and from there on back they are the old ones.
    Each change's stretch, from _REACH nodes before it (times 4 until its first value meets the old), up to the
    node after it (its old value as the stretch's end), is solved in one ``descend`` of the stretches laid end
    to end (no map between them: each starts from its own end value). Past a quarter of the nodes, ``descend``
    itself: stretches that long save little, and a second try where the first fell short would cost more."""
    n = len(cap) - 1
    changed = np.flatnonzero(cap != old_cap)
    if not len(changed):
        return old.copy()
    reach = _REACH
    while True:
        end = np.minimum(changed + 1, n)
        lo = np.maximum(changed - reach, 0)
        first = np.r_[True, lo[1:] > end[:-1]]  # stretches that share a node are one
        lo, end = lo[first], end[np.r_[first[1:], True]]
        size = end - lo + 1
        if int(size.sum()) > n // 4:
            return descend(cap, a, b)
        nodes = np.repeat(end - size + 1, size) + ranks(size) - 1  # lo .. end of each stretch
        last = np.cumsum(size) - 1  # each stretch's end among them
        c = cap[nodes]
        c[last] = np.where(end < n, old[end], cap[n])
        steps = nodes[:-1]
        gap = last[:-1]  # from each stretch's end to the next one's start: no map
        y = descend(c, [_cut(ai[steps], gap, 1.0) for ai in a], [_cut(bi[steps], gap, np.inf) for bi in b])
        met = (lo == 0) | (np.abs(y[last - size + 1] - old[lo]) <= _MET * old[lo])
        if met.all():
            out = old.copy()
            out[nodes] = y
            return out
        reach *= 4


def _cut(v: np.ndarray, at: np.ndarray, fill: float) -> np.ndarray:
    """v (a fresh copy) with ``fill`` at ``at``: the steps between stretches, which change nothing."""
    v[at] = fill
    return v


def _chosen(a_blk: np.ndarray, b_blk: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """At each step the least of the axes' maps at the value after it, ``x`` (step, block) (step 1's binding
    axes): its a and b, (step, block). On a tie the first, as the axes come."""
    values = a_blk * x[:, :, None]
    values += b_blk
    return _picked(a_blk, b_blk, values.argmin(axis=2))


def _picked(a_blk: np.ndarray, b_blk: np.ndarray, picks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The a and b of map ``picks`` (step, block) at each step of every block (contiguous (step, block, map)
    arrays: one flat take each, a third of np.take_along_axis's time)."""
    flat = picks + np.arange(0, a_blk.size, a_blk.shape[2]).reshape(picks.shape)  # + each step's and block's first map
    return a_blk.reshape(-1).take(flat), b_blk.reshape(-1).take(flat)


def _composed(c_blk: np.ndarray, a_sel: np.ndarray, b_sel: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each block's steps y -> min(c, a y + b), one map a step, composed into one map min(C, A y + B) of the
    value after its last step (step 1)."""
    nb = c_blk.shape[1]
    big_a, big_b, big_c = np.ones(nb), np.zeros(nb), np.full(nb, np.inf)
    for cj, aj, bj in zip(c_blk[::-1], a_sel[::-1], b_sel[::-1]):
        big_c = np.minimum(cj, aj * big_c + bj)
        big_b = aj * big_b + bj
        big_a = aj * big_a
    return big_c, big_a, big_b


def _run(c_blk: np.ndarray, a_blk: np.ndarray, b_blk: np.ndarray, x_in: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every block run from its input ``x_in`` (the value after its last step) with, at each step, the least of
    the axes' maps (step 2; on a tie the first). ``a_blk`` and ``b_blk`` are (step, block, map) arrays: each
    step's maps of every block one contiguous row, so a step chooses with one argmin along rows and one flat
    take (numpy's own cost per call, not the arithmetic, bounds a run of the short programs' 60 blocks).
    Returns the values and the map chosen at each step, (step, block) both; the maps are composed only
    where another round needs them (``_composed``)."""
    steps, nb, n_maps = a_blk.shape
    y_blk, picks = np.empty_like(c_blk), np.empty((steps, nb), dtype=np.intp)
    rows = np.arange(0, nb * n_maps, n_maps)  # each block's first map in a step's flat row
    x = x_in
    for aj, bj, cj, pj, yj in zip(a_blk[::-1], b_blk[::-1], c_blk[::-1], picks[::-1], y_blk[::-1]):
        values = aj * x[:, None]
        values += bj
        pick = values.argmin(axis=1, out=pj)
        x = np.minimum(cj, values.ravel().take(pick + rows), out=yj)
    return y_blk, picks


def _blocks(v: np.ndarray | list[np.ndarray], fill: float) -> np.ndarray:
    """v padded to whole blocks, as (step, block): each row one step of every block; a list of such vectors
    (the maps of every axis) as (step, block, map), each written in place (one fresh array), _GATHER blocks at a
    time: every map of those blocks is written while their part of the array is in cache (a third of the time
    of one map at a time over the whole array, each write then a cache line of its own: 3D_Chips 25 -> 8.5 ms)."""
    rows = v if isinstance(v, list) else [v]
    n = len(rows[0])
    whole, rest = divmod(n, _BLOCK)
    out = np.empty((_BLOCK, whole + (rest > 0), len(rows)))
    for start in range(0, whole, _GATHER):
        stop = min(start + _GATHER, whole)
        part = out[:, start:stop]
        for i, vi in enumerate(rows):
            part[:, :, i] = vi[start * _BLOCK:stop * _BLOCK].reshape(stop - start, _BLOCK).T
    for i, vi in enumerate(rows):
        out[:rest, whole:, i] = vi[whole * _BLOCK:, None]
    out[rest:, whole:] = fill
    return out if isinstance(v, list) else out[:, :, 0]


def _chain(c: np.ndarray, a: np.ndarray, b: np.ndarray, end: float) -> np.ndarray:
    """y_k = min(c_k, a_k y_{k+1} + b_k) for k = n-1 .. 0 from y_n = end; returns y_0 .. y_{n-1} (step 1)."""
    n = len(a)
    if n <= _SHORT:  # in Python floats, collected in a list (writing each into an array costs as much as its step)
        y = []
        x = end
        for ck, ak, bk in zip(c.tolist()[::-1], a.tolist()[::-1], b.tolist()[::-1]):
            x = min(ck, ak * x + bk)
            y.append(x)
        return np.array(y[::-1])
    c_blk, a_blk, b_blk = _blocks(c, np.inf), _blocks(a, 1.0), _blocks(b, 0.0)
    first = _chain(*_composed(c_blk, a_blk, b_blk), end)  # each block's first value
    y_blk = np.empty_like(c_blk)
    row = _then(first[1:], end)  # the value after each block's current step
    for cj, aj, bj, yj in zip(c_blk[::-1], a_blk[::-1], b_blk[::-1], y_blk[::-1]):
        row = np.minimum(cj, aj * row + bj, out=yj)
    return y_blk.T.reshape(-1)[:n]


def _then(v: np.ndarray, end: float) -> np.ndarray:
    """v with ``end`` after it (np.r_ parses its arguments first: a few microseconds a round)."""
    return np.concatenate((v, (end,)))


def _sequential(cap, a, b):
    """Short recursions step by step."""
    n = len(cap) - 1
    y = np.empty(n + 1)
    y[n] = x = float(cap[n])
    rows = [list(zip(ai.tolist(), bi.tolist())) for ai, bi in zip(a, b)]
    for k in range(n - 1, -1, -1):
        x = min([float(cap[k])] + [r[k][0] * x + r[k][1] for r in rows])
        y[k] = x
    return y
