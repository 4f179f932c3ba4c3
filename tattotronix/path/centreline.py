"""Line art as single strokes: a skeleton (one pixel wide) to the fewest pen strokes.

The skeleton comes from scikit-image's ``skeletonize``; this module turns its pixels into
polylines that draw every skeleton branch exactly once, in the fewest strokes:

1. **Graph.** Skeleton pixels are joined to their 4-neighbours, and to a diagonal
   neighbour only when no shared 4-neighbour is on the skeleton (so a corner step is one
   edge, not a triangle). Pixels of degree 2 are inside a branch; the others (ends and
   junctions) are the graph's nodes. A closed ring with no node is a loop on its own.
2. **Spurs.** Branches from an end to a junction shorter than ``prune_px``, or than a
   few of the line's half-widths at the junction, are thinning artefacts (a line's
   flared end, a corner of the line or of a wider part) and are removed; the skeleton is
   rebuilt until none is left.
3. **Fewest strokes.** Each connected piece of the graph with ``2k`` odd nodes (k > 0)
   needs exactly ``k`` strokes to draw each branch once (Euler); with none, one closed
   stroke. The odd nodes are paired (nearest first), the pairs joined by virtual branches,
   an Euler circuit found (Hierholzer) and cut at the virtual branches.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np
from numpy.typing import NDArray

__all__ = ["SPUR_HALF_WIDTHS", "skeleton_strokes"]

Pixels = NDArray[np.intp]  # (n, 2) (row, col)

_N4 = ((-1, 0), (1, 0), (0, -1), (0, 1))
_DIAG = ((-1, -1), (-1, 1), (1, -1), (1, 1))


def _neighbours(on: set[tuple[int, int]], p: tuple[int, int]) -> list[tuple[int, int]]:
    """The graph neighbours of skeleton pixel ``p`` (see the module docstring)."""
    r, c = p
    out = [(r + dr, c + dc) for dr, dc in _N4 if (r + dr, c + dc) in on]
    for dr, dc in _DIAG:
        q = (r + dr, c + dc)
        if q in on and (r + dr, c) not in on and (r, c + dc) not in on:
            out.append(q)
    return out


def _branches(on: set[tuple[int, int]]) -> list[list[tuple[int, int]]]:
    """Every branch as a pixel chain from node to node (or a closed ring, first pixel
    repeated), each edge of the graph in exactly one chain."""
    nbr = {p: _neighbours(on, p) for p in on}
    nodes = {p for p, n in nbr.items() if len(n) != 2}
    seen: set[frozenset[tuple[int, int]]] = set()  # edges walked
    chains: list[list[tuple[int, int]]] = []

    def walk(a: tuple[int, int], b: tuple[int, int]) -> list[tuple[int, int]]:
        chain = [a, b]
        seen.add(frozenset((a, b)))
        prev, cur = a, b
        while cur not in nodes and cur != a:
            nxt = [q for q in nbr[cur] if q != prev and frozenset((cur, q)) not in seen]
            if not nxt:
                break
            prev, cur = cur, nxt[0]
            seen.add(frozenset((prev, cur)))
            chain.append(cur)
        return chain

    for a in sorted(nodes):
        for b in nbr[a]:
            if frozenset((a, b)) not in seen:
                chains.append(walk(a, b))
    for a in sorted(on - nodes):  # rings with no node
        for b in nbr[a]:
            if frozenset((a, b)) not in seen:
                chains.append(walk(a, b))
    return chains


#: a spur no longer than this many times the line's half-width at its junction is the
#: skeleton of a corner, not a branch: a corner of angle a grows a spur of
#: ``r (1 / sin(a / 2) - 1)`` toward its outer tip (1.2 r at 53 degrees, 2.9 r at 30)
SPUR_HALF_WIDTHS = 3.0


def _prune(on: set[tuple[int, int]], prune_px: float,
           depth: NDArray[np.floating] | None = None) -> set[tuple[int, int]]:
    """Remove spurs (end-to-junction branches shorter than ``prune_px``, or than
    :data:`SPUR_HALF_WIDTHS` times ``depth`` at their junction) until none is left; a
    branch between two ends (a whole short line) is kept."""
    while True:
        nbr_count = {p: len(_neighbours(on, p)) for p in on}
        drop: set[tuple[int, int]] = set()
        for chain in _branches(on):
            a, b = chain[0], chain[-1]
            ends = [nbr_count[a] == 1, nbr_count[b] == 1]
            if ends[0] == ends[1]:
                continue
            junction = b if ends[0] else a
            limit = prune_px if depth is None else max(
                prune_px, SPUR_HALF_WIDTHS * float(depth[junction]))
            if _length(chain) >= limit:
                continue
            drop.update(chain[:-1] if ends[0] else chain[1:])  # keep the junction
        if not drop:
            return on
        on = on - drop


def _length(chain: list[tuple[int, int]]) -> float:
    p = np.asarray(chain, dtype=np.float64)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


def _euler_strokes(chains: list[list[tuple[int, int]]]) -> list[list[tuple[int, int]]]:
    """Join branches into the fewest strokes that draw each once (see the module
    docstring); each stroke is a pixel chain."""
    # a multigraph over the chain end pixels; edge i is chains[i], virtual edges after
    ends: dict[tuple[int, int], list[int]] = defaultdict(list)
    edges: list[tuple[tuple[int, int], tuple[int, int]]] = []
    for i, ch in enumerate(chains):
        edges.append((ch[0], ch[-1]))
        ends[ch[0]].append(i)
        ends[ch[-1]].append(i)
    n_real = len(edges)
    # connected pieces (union-find over the end pixels)
    parent: dict[tuple[int, int], tuple[int, int]] = {p: p for p in ends}

    def find(p: tuple[int, int]) -> tuple[int, int]:
        while parent[p] != p:
            parent[p] = parent[parent[p]]
            p = parent[p]
        return p

    for a, b in edges:
        parent[find(a)] = find(b)
    odd_by_piece: dict[tuple[int, int], list[tuple[int, int]]] = defaultdict(list)
    for p, inc in sorted(ends.items()):
        if len(inc) % 2:
            odd_by_piece[find(p)].append(p)
    for odd in odd_by_piece.values():  # pair the odd nodes, nearest first
        left = list(odd)
        while left:
            a = left.pop(0)
            d = [abs(a[0] - b[0]) + abs(a[1] - b[1]) for b in left]
            b = left.pop(int(np.argmin(d)))
            ends[a].append(len(edges))
            ends[b].append(len(edges))
            edges.append((a, b))
    used = [False] * len(edges)
    strokes: list[list[tuple[int, int]]] = []
    for start in sorted(ends):
        if all(used[e] for e in ends[start]):
            continue
        # Hierholzer from an odd node of this piece if it has one, so the circuit's cuts
        # fall on virtual edges
        circuit = _circuit(start, ends, edges, used)
        strokes.extend(_cut(circuit, chains, n_real))
    return strokes


def _circuit(start: tuple[int, int], ends: dict[tuple[int, int], list[int]],
             edges: list[tuple[tuple[int, int], tuple[int, int]]], used: list[bool]
             ) -> list[tuple[int, bool]]:
    """An Euler circuit from ``start`` over the unused edges of its piece, as (edge,
    forward) steps (Hierholzer, iterative)."""
    stack: list[tuple[tuple[int, int], int, bool]] = [(start, -1, True)]
    out: list[tuple[int, bool]] = []
    ptr: dict[tuple[int, int], int] = defaultdict(int)
    while stack:
        v, e_in, fwd_in = stack[-1]
        inc = ends[v]
        while ptr[v] < len(inc) and used[inc[ptr[v]]]:
            ptr[v] += 1
        if ptr[v] < len(inc):
            e = inc[ptr[v]]
            used[e] = True
            a, b = edges[e]
            fwd = a == v
            stack.append((b if fwd else a, e, fwd))
        else:
            stack.pop()
            if e_in >= 0:
                out.append((e_in, fwd_in))
    out.reverse()
    return out


def _cut(circuit: list[tuple[int, bool]], chains: list[list[tuple[int, int]]], n_real: int
         ) -> list[list[tuple[int, int]]]:
    """Cut a circuit at its virtual edges into strokes of pixel chains."""
    if not circuit:
        return []
    virt = [i for i, (e, _) in enumerate(circuit) if e >= n_real]
    if virt:  # start right after a virtual edge, so each cut falls between strokes
        k = virt[0] + 1
        circuit = circuit[k:] + circuit[:k]
    strokes: list[list[tuple[int, int]]] = []
    cur: list[tuple[int, int]] = []
    for e, fwd in circuit:
        if e >= n_real:
            if cur:
                strokes.append(cur)
            cur = []
            continue
        ch = chains[e] if fwd else chains[e][::-1]
        cur.extend(ch if not cur else ch[1:])
    if cur:
        strokes.append(cur)
    return strokes


def skeleton_strokes(skeleton: NDArray[np.bool_], prune_px: float = 0.0,
                     depth: NDArray[np.floating] | None = None) -> list[Pixels]:
    """The fewest strokes that draw every branch of a skeleton once.

    Args:
        skeleton: (H, W) bool, a one-pixel-wide skeleton (``skimage.morphology.skeletonize``).
        prune_px: remove end-to-junction spurs shorter than this (pixels of arc length).
        depth: (H, W) the line's half-width at each pixel (its distance to the edge, px):
            spurs up to :data:`SPUR_HALF_WIDTHS` half-widths long at their junction (a
            corner's) go too, so a zigzag is one stroke, not one per leg.

    Returns:
        The strokes, each an (n, 2) int (row, col) pixel chain, consecutive pixels
        8-adjacent; a closed stroke repeats its first pixel at the end. An isolated pixel
        is a stroke of one pixel.
    """
    rows, cols = np.nonzero(skeleton)
    on = {(int(r), int(c)) for r, c in zip(rows, cols, strict=True)}
    if prune_px > 0 or depth is not None:
        on = _prune(on, prune_px, depth)
    singles = [p for p in sorted(on) if not _neighbours(on, p)]
    strokes = _euler_strokes(_branches(on))
    out = [np.asarray(s, dtype=np.intp) for s in strokes]
    out.extend(np.asarray([p], dtype=np.intp) for p in singles)
    return out

