"""Disjunctive normal form of a CSG graph: a union of intersections of quadrics (eq. 17–18).

``to_normal_form`` pushes complements to the leaves (De Morgan), composes the transforms along
every root-to-leaf path and applies them to the leaf's matrix (``Q' = M⁻ᵀ Q M⁻¹``, eq. 17),
duplicates shared sub-graphs per path and distributes intersections over unions, giving

    S = ∪ᵢ ∩ⱼ Q_ij                                                    (eq. 18)

Three simplifications keep the form small and the sampler well-posed:

* a quadric repeated within a term is kept once (``A ∩ A = A``);
* a term holding a surface with both orientations is dropped (``A ∩ ¬A`` has no interior);
* a term that contains every quadric of another term is dropped (absorption, ``X ∪ (X ∩ Y) = X``).

Surfaces are matched up to scale and sign with a relative tolerance (``tolerances.SURFACE``):
``surface[k]`` numbers the distinct surfaces and ``orientation[k]`` (±1) says whether quadric k
equals its surface's representative or its complement. The relative distance of eq. 22 uses
these to treat one surface reached through several terms (:mod:`csgnb.csg.distance`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from csgnb.csg.graph import Complement, Difference, Intersection, Leaf, Node, Transformed, Union, _leaf_paths, as_node
from csgnb.errors import CsgnbError
from csgnb.quadric import tolerances as tol
from csgnb.quadric.arguments import as_count, as_matrix
from csgnb.quadric.quadric import Quadric, apply_inverse, moved_placements, transform_inverse

__all__ = ["NormalForm", "to_normal_form", "quadric_coefficients"]

_UPPER = (np.array([0, 0, 0, 1, 1, 2]), np.array([0, 1, 2, 1, 2, 2]))
_TRIU_FLAT = np.flatnonzero(np.triu(np.ones((4, 4), dtype=bool)))


def quadric_coefficients(quadrics) -> np.ndarray:
    """Return the kernel layout of quadrics : (n, 12) float64.

    Row k is ``(a00, a01, a02, a11, a12, a22, m0, m1, m2, c, λ_min, λ_max)`` with ``m = Q[:3, 3]``
    (= -b) and λ the extreme eigenvalues of A: the 10 distinct matrix entries of §6's quadric
    buffer plus what the conservative distance (eq. 12) needs.
    """
    if isinstance(quadrics, Quadric) or not hasattr(quadrics, "__iter__") or isinstance(quadrics, str | bytes):
        raise TypeError(f"quadrics must be an iterable of csgnb.quadric.Quadric, got {type(quadrics).__name__}")
    qs = list(quadrics)
    for q in qs:
        if not isinstance(q, Quadric):
            raise TypeError(f"quadrics must hold csgnb.quadric.Quadric objects, got a {type(q).__name__}")
    if not qs:
        return np.empty((0, 12))
    M = np.array([q.matrix for q in qs])
    return coefficients_of_matrices(M)


def coefficients_of_matrices(M: np.ndarray) -> np.ndarray:
    """Return the kernel layout (see :func:`quadric_coefficients`) of matrices ``M`` : (n, 4, 4)."""
    out = np.empty((len(M), 12))
    out[:, :6] = M[:, _UPPER[0], _UPPER[1]]
    out[:, 6:9] = M[:, :3, 3]
    out[:, 9] = M[:, 3, 3]
    lam = np.linalg.eigvalsh(M[:, :3, :3]) if len(M) else np.empty((0, 3))
    out[:, 10], out[:, 11] = lam[:, 0], lam[:, -1]
    return out


@dataclass(frozen=True, eq=False)
class NormalForm:
    """A CSG object as a union of intersection terms of quadrics (eq. 18).

    quadrics : tuple of Quadric, length n — term-major: term i holds
        ``quadrics[term_start[i]:term_start[i + 1]]`` (transforms already applied).
    term_start : (T + 1,) int64 — term offsets.
    names : tuple of str or None — the leaf name each quadric came from.
    surface : (n,) int64 — id of the geometric surface (equal up to scale and sign).
    orientation : (n,) int8 — +1 if the quadric is its surface's representative, -1 if its complement.
    """

    quadrics: tuple[Quadric, ...]
    term_start: np.ndarray
    names: tuple[str | None, ...]
    surface: np.ndarray
    orientation: np.ndarray
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def n_terms(self) -> int:
        """Number of intersection terms T."""
        return len(self.term_start) - 1

    def __len__(self) -> int:
        return len(self.quadrics)

    @cached_property
    def term_of(self) -> np.ndarray:
        """Term index of each quadric : (n,) int64."""
        return np.repeat(np.arange(self.n_terms, dtype=np.int64), np.diff(self.term_start))

    @cached_property
    def coefficients(self) -> np.ndarray:
        """Kernel layout of the quadrics : (n, 12) float64 (see :func:`quadric_coefficients`)."""
        c = quadric_coefficients(self.quadrics)
        c.setflags(write=False)
        return c

    def term(self, i: int) -> np.ndarray:
        """Return the quadric indices of term ``i`` : (m,) int64."""
        return np.arange(self.term_start[i], self.term_start[i + 1], dtype=np.int64)

    def terms(self) -> list[list[Quadric]]:
        """Return the terms as lists of quadrics."""
        return [list(self.quadrics[self.term_start[i] : self.term_start[i + 1]]) for i in range(self.n_terms)]

    # -- evaluation ---------------------------------------------------------------------------
    def signed_distance(self, points) -> np.ndarray:
        """Return the conservative signed distance to the CSG surface, eq. 19 : (n,) float64."""
        from csgnb.csg.distance import csg_distance

        return csg_distance(self, points)

    def relative_distance(self, index: int, points) -> np.ndarray:
        """Return d_Qab(S, p) of eq. 22 for quadric ``index`` at ``points`` : (n,) float64."""
        from csgnb.csg.distance import relative_distance

        return relative_distance(self, index, points)

    def classify(self, points) -> np.ndarray:
        """Return -1 (inside), 0 (on a quadric that decides), +1 (outside) : (n,) int8.

        The sign of ``minᵢ maxⱼ Q_ij(p)`` (quadric values, no tolerance).
        """
        from csgnb.csg.distance import csg_value

        return np.sign(csg_value(self, points)).astype(np.int8)

    def mapped(self, matrix) -> NormalForm:
        """Return this normal form with every quadric mapped by the 4×4 ``matrix`` (eq. 17).

        Terms, names and surface ids are kept (a map keeps surfaces distinct).
        """
        matrix = as_matrix(matrix, "matrix")
        Minv = transform_inverse(matrix)
        if not self.quadrics:
            return self
        M = np.array([q.matrix for q in self.quadrics])
        if Minv[3, 0] == 0.0 and Minv[3, 1] == 0.0 and Minv[3, 2] == 0.0 and Minv[3, 3] == 1.0:
            # affine: blockwise, as ``quadric.apply_inverse``, for all quadrics at once
            Li, sv = Minv[:3, :3], Minv[:3, 3]
            A, m, c = M[:, :3, :3], M[:, :3, 3], M[:, 3, 3]
            As_m = A @ sv + m
            out = np.empty_like(M)
            out[:, :3, :3] = Li.T @ A @ Li
            out[:, :3, 3] = As_m @ Li
            out[:, 3, :3] = out[:, :3, 3]
            out[:, 3, 3] = np.einsum("i,ni->n", sv, A @ sv) + 2.0 * (m @ sv) + c
        else:
            out = np.einsum("ji,njk,kl->nil", Minv, M, Minv)
        out = 0.5 * (out + out.transpose(0, 2, 1))
        affine = Minv[3, 0] == 0.0 and Minv[3, 1] == 0.0 and Minv[3, 2] == 0.0 and Minv[3, 3] == 1.0
        # placed quadrics (``Quadric.placement``) are mapped through their placement: exact far away
        placed = [q for q in self.quadrics if q.placement is not None] if affine else []
        moved = iter(moved_placements(placed, matrix, Minv) if placed else ())
        qs = [next(moved) if affine and q0.placement is not None else Quadric._trusted(q, symmetric=True)
              for q0, q in zip(self.quadrics, out, strict=True)]
        return NormalForm(tuple(qs), self.term_start, self.names, self.surface, self.orientation)

    def __repr__(self) -> str:
        sizes = np.diff(self.term_start).tolist()
        return f"NormalForm({len(self.quadrics)} quadrics in {self.n_terms} terms of sizes {sizes})"


class _Registry:
    """Distinct surfaces seen so far, matched up to scale and sign."""

    def __init__(self) -> None:
        self.vectors = np.empty((16, 10))
        self.count = 0
        self.quadric: dict[tuple[int, int], Quadric] = {}
        self.name: dict[tuple[int, int], str | None] = {}

    def key(self, q: Quadric, name: str | None) -> tuple[int, int]:
        w = q.matrix.ravel()[_TRIU_FLAT]
        w = w / np.abs(w).max()
        V = self.vectors[: self.count]
        k = None
        if self.count:
            for orient in (1, -1):
                close = (np.abs(V - orient * w).max(axis=1) <= tol.SURFACE).nonzero()[0]
                if len(close):
                    k = (int(close[0]), orient)
                    break
        if k is None:
            if self.count == len(self.vectors):
                self.vectors = np.vstack([self.vectors, np.empty_like(self.vectors)])
            self.vectors[self.count] = w
            self.count += 1
            k = (self.count - 1, 1)
        if k not in self.quadric:
            self.quadric[k] = q
            self.name[k] = name
        return k


Term = frozenset  # of (surface, orientation) keys


def _simplify(terms: list[Term]) -> list[Term]:
    """Drop empty-interior terms, duplicates and absorbed terms, keeping first-seen order."""
    kept: list[Term] = []
    for t in terms:
        if any((s, -o) in t for s, o in t):
            continue  # Q ∩ ¬Q
        kept.append(t)
    order = sorted(range(len(kept)), key=lambda i: (len(kept[i]), i))
    survivors: list[int] = []
    for i in order:
        t = kept[i]
        if any(kept[j] <= t for j in survivors):
            continue
        survivors.append(i)
    return [kept[i] for i in sorted(survivors)]


class _Converter:
    def __init__(self, max_terms: int) -> None:
        self.max_terms = max_terms
        self.registry = _Registry()
        self.memo: dict[tuple, list[Term]] = {}
        self.leaf_memo: dict[tuple, tuple[int, int]] = {}
        self.inverse: dict[bytes, np.ndarray] = {}
        self.moved: dict[tuple[int, bytes], Quadric] = {}  # leaves mapped ahead (:meth:`prepare`)

    def prepare(self, root: Node, M: np.ndarray) -> None:
        """Map the leaves' quadrics ahead of :meth:`convert`, those under one affine path map in one batch
        (:func:`~csgnb.quadric.quadric.moved_placements`: one call instead of one per leaf, the same matrices)."""
        groups: dict[bytes, tuple[np.ndarray, dict[int, Quadric]]] = {}
        for node, P in _leaf_paths(root, M):
            if node.quadric.placement is not None and P[3, 0] == 0.0 and P[3, 1] == 0.0 and P[3, 2] == 0.0 \
                    and P[3, 3] != 0.0:  # (the placed leaves :meth:`_leaf_quadric` moves by ``P``)
                groups.setdefault(P.tobytes(), (P, {}))[1][id(node.quadric)] = node.quadric
        for pkey, (P, leaves) in groups.items():
            Minv = self.inverse.get(pkey)
            if Minv is None:
                Minv = self.inverse[pkey] = transform_inverse(P, "the transform along a path to a leaf")
            qs = list(leaves.values())
            for q, moved in zip(qs, moved_placements(qs, P, Minv), strict=True):
                self.moved[(id(q), pkey)] = moved

    def _leaf_quadric(self, q: Quadric, M: np.ndarray | None, mkey: bytes | None) -> Quadric:
        if M is None:
            return q
        ready = self.moved.get((id(q), mkey))
        if ready is not None:
            return ready
        Minv = self.inverse.get(mkey)
        if Minv is None:  # a composed path map: checked once (a product of good maps can be singular)
            Minv = self.inverse[mkey] = transform_inverse(M, "the transform along a path to a leaf")
        placement = q.placement
        if placement is not None:
            # a quadric built in its own frame and moved by ``origin``: compose the move with the path
            # map first, so that the path map (the sampler's frame: near the model) sees its exact shape
            # rather than world coefficients that lost digits (a unit sphere at 10⁹ has c = 10¹⁸ − 1);
            # an affine path keeps the placement (mapped back to world, the normal form stays exact)
            if M[3, 0] == 0.0 and M[3, 1] == 0.0 and M[3, 2] == 0.0 and M[3, 3] != 0.0:
                return q._transformed(M, Minv)  # (M's inverse checked once above)
            local, origin = placement
            T = np.eye(4)
            T[:3, 3] = origin
            return Quadric._trusted(apply_inverse(local, transform_inverse(M @ T, "the transform along a path "
                                                                                 "to a leaf")))
        return Quadric._trusted(apply_inverse(q.matrix, Minv))

    def _check(self, terms: list[Term]) -> list[Term]:
        if len(terms) > self.max_terms:
            raise CsgnbError(
                f"the normal form exceeds {self.max_terms} terms (distributing intersections over unions "
                "grows exponentially); simplify the graph or pass a larger max_terms"
            )
        return terms

    def _product(self, factors: list[list[Term]]) -> list[Term]:
        acc: list[Term] = [frozenset()]
        for f in factors:
            acc = self._check(_simplify([a | b for a in acc for b in f]))
            if not acc:
                break
        return acc

    def _sum(self, parts: list[list[Term]]) -> list[Term]:
        return self._check(_simplify([t for p in parts for t in p]))

    def convert(self, node: Node, M: np.ndarray | None, neg: bool) -> list[Term]:
        mkey = None if M is None else M.tobytes()
        key = (id(node), mkey, neg)
        hit = self.memo.get(key)
        if hit is not None:
            return hit
        if isinstance(node, Leaf):
            lk = (id(node), mkey, neg)
            k = self.leaf_memo.get(lk)
            if k is None:
                q = self._leaf_quadric(node.quadric, M, mkey)
                k = self.registry.key(q.complement() if neg else q, node.name)
                self.leaf_memo[lk] = k
            out = [frozenset([k])]
        elif isinstance(node, Transformed):
            out = self.convert(node.child, node.matrix if M is None else M @ node.matrix, neg)
        elif isinstance(node, Complement):
            out = self.convert(node.child, M, not neg)
        elif isinstance(node, Union | Intersection):
            parts = [self.convert(c, M, neg) for c in node.operands]
            out = self._product(parts) if isinstance(node, Intersection) != neg else self._sum(parts)
        elif isinstance(node, Difference):
            parts = [self.convert(node.base, M, neg)] + [self.convert(s, M, not neg) for s in node.subtrahends]
            out = self._sum(parts) if neg else self._product(parts)
        else:
            raise TypeError(f"unknown CSG node type {type(node).__name__}")
        self.memo[key] = out  # ids are stable: the root keeps every node alive during the conversion
        return out


def to_normal_form(root, max_terms: int = 4096, frame=None) -> NormalForm:
    """Return the disjunctive normal form of a CSG graph (eq. 17–18).

    Parameters
    ----------
    root : Node or Quadric
        The graph (a bare quadric is one leaf).
    max_terms : int
        Limit on the number of terms; the conversion can grow exponentially with the depth of
        alternating unions and intersections, and raises :class:`CsgnbError` beyond the limit.
    frame : (4, 4) float64 or None
        A map applied at the root (composed with every path's transforms before any leaf is
        transformed): the sampler passes its normalised frame, so that a model far from the
        origin keeps the precision of its leaves. Without it, surfaces are still matched in a
        normalised frame (:func:`csgnb.csg.normalisation.graph_frame`) and the result is mapped
        back to world coordinates: matching world matrices would merge distinct surfaces of a
        model far from the origin, whose coefficients differ only in their 13th digit.

    Returns
    -------
    NormalForm
        Possibly with zero terms (an empty object such as ``A ∩ ¬A``).
    """
    conv = _Converter(as_count(max_terms, "max_terms", 1))
    root = as_node(root)
    if frame is None:
        from csgnb.csg.normalisation import graph_frame

        provisional = graph_frame(root)
        return _convert(conv, root, provisional.matrix).mapped(provisional.inverse)
    return _convert(conv, root, as_matrix(frame, "frame"))


def _convert(conv: _Converter, root: Node, F: np.ndarray) -> NormalForm:
    conv.prepare(root, F)
    terms = conv.convert(root, F, False)
    quadrics: list[Quadric] = []
    names: list[str | None] = []
    surface: list[int] = []
    orientation: list[int] = []
    starts = [0]
    for t in terms:
        for k in sorted(t):
            quadrics.append(conv.registry.quadric[k])
            names.append(conv.registry.name[k])
            surface.append(k[0])
            orientation.append(k[1])
        starts.append(len(quadrics))
    sid = np.array(surface, dtype=np.int64)
    orient = np.array(orientation, dtype=np.int8)
    ts = np.array(starts, dtype=np.int64)
    for a in (sid, orient, ts):
        a.setflags(write=False)
    return NormalForm(tuple(quadrics), ts, tuple(names), sid, orient)
