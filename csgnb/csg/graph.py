"""CSG graphs over quadrics: leaves, Boolean operations and transforms on edges (paper §5).

A CSG object is a directed acyclic graph. Leaves hold a :class:`~csgnb.quadric.Quadric`
(inside where ``Q < 0``); inner nodes are Boolean operations — :class:`Union` and
:class:`Intersection` (variadic), :class:`Difference` (one base minus any number of
subtrahends) and :class:`Complement`. A :class:`Transformed` node is the annotation of an edge
with a 4×4 matrix: its child is mapped by the matrix (``x ↦ M x``). Nodes are immutable and
compared by identity, so one node used twice is a *shared sub-graph*; the normal form
(:mod:`csgnb.csg.normal_form`) duplicates it per path.

Build graphs with the functions below or with operators::

    (a & b) | c          # union of an intersection and c
    a - b                # difference
    ~a                   # complement
    a.translated((1, 0, 0))
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import numpy as np

from csgnb.errors import CsgnbError, GeometryError
from csgnb.quadric.arguments import as_finite_array as _finite  # one check for quadrics and transforms
from csgnb.quadric.arguments import as_matrix, as_real
from csgnb.quadric.quadric import Quadric, transform_inverse

__all__ = [
    "Node",
    "Leaf",
    "Union",
    "Intersection",
    "Difference",
    "Complement",
    "Transformed",
    "leaf",
    "union",
    "intersection",
    "difference",
    "complement",
    "transformed",
    "as_node",
    "rotation_matrix",
    "graph_leaves",
    "graph_size",
]


class Node:
    """Base class of CSG graph nodes (immutable; equality is identity)."""

    __slots__ = ()

    def __or__(self, other) -> Union:
        return union(self, other)

    def __ror__(self, other) -> Union:
        return union(other, self)

    def __and__(self, other) -> Intersection:
        return intersection(self, other)

    def __rand__(self, other) -> Intersection:
        return intersection(other, self)

    def __sub__(self, other) -> Difference:
        return difference(self, other)

    def __rsub__(self, other) -> Difference:
        return difference(other, self)

    def __invert__(self) -> Complement:
        return complement(self)

    def children(self) -> tuple[Node, ...]:
        """Return the child nodes (empty for a leaf)."""
        return ()

    # -- transforms (edge annotations) ---------------------------------------------------
    def transformed(self, matrix) -> Transformed:
        """Return this node mapped by the 4×4 (or 3×4 affine) ``matrix`` (an annotated edge)."""
        return Transformed(self, matrix)

    def translated(self, offset) -> Transformed:
        """Return this node moved by ``offset`` : (3,)."""
        m = np.eye(4)
        m[:3, 3] = _finite(offset, (3,), "offset")
        return Transformed(self, m)

    def rotated(self, axis, angle: float, center=(0.0, 0.0, 0.0)) -> Transformed:
        """Return this node rotated by ``angle`` (radians) about ``axis`` : (3,) through ``center``."""
        return Transformed(self, rotation_matrix(axis, angle, center))

    def scaled(self, factors, center=(0.0, 0.0, 0.0)) -> Transformed:
        """Return this node scaled by ``factors`` (scalar or (3,)) about ``center``."""
        f = _finite(factors, None, "factors")
        if f.shape not in ((), (1,), (3,)):
            raise CsgnbError(f"factors must be a number or 3 numbers, got shape {f.shape}")
        f = np.broadcast_to(f, (3,)).astype(np.float64)
        c = _finite(center, (3,), "center")
        m = np.diag([*f, 1.0])
        m[:3, 3] = c - f * c
        return Transformed(self, m)

    # -- conversion ------------------------------------------------------------------------
    def normal_form(self, max_terms: int = 4096):
        """Return the disjunctive normal form (eq. 17–18); see :func:`csgnb.csg.to_normal_form`."""
        from csgnb.csg.normal_form import to_normal_form

        return to_normal_form(self, max_terms=max_terms)

    def _label(self) -> str:
        return type(self).__name__

    def __repr__(self) -> str:
        kids = ", ".join(repr(c) for c in self.children())
        return f"{self._label()}({kids})"


class Leaf(Node):
    """A primitive: the solid ``{x : Q(x) ≤ 0}`` of a quadric, with an optional display name."""

    __slots__ = ("quadric", "name")

    def __init__(self, quadric: Quadric, name: str | None = None) -> None:
        if not isinstance(quadric, Quadric):
            raise TypeError(f"a leaf holds a csgnb.quadric.Quadric, got {type(quadric).__name__}")
        if name is not None and not isinstance(name, str):
            raise TypeError(f"a leaf's name must be a str or None, got {type(name).__name__}")
        self.quadric = quadric
        self.name = name

    def _label(self) -> str:
        return f"Leaf({self.name!r})" if self.name else "Leaf"

    def __repr__(self) -> str:
        return self._label()


class _Variadic(Node):
    __slots__ = ("operands",)

    def __init__(self, operands: Iterable) -> None:
        ops = tuple(as_node(o) for o in operands)
        if not ops:
            raise CsgnbError(f"{type(self).__name__} needs at least one operand")
        self.operands = ops

    def children(self) -> tuple[Node, ...]:
        return self.operands


class Union(_Variadic):
    """The union of its operands (variadic)."""

    __slots__ = ()


class Intersection(_Variadic):
    """The intersection of its operands (variadic)."""

    __slots__ = ()


class Difference(Node):
    """``base`` minus every subtrahend: ``base ∩ ¬s₁ ∩ ¬s₂ ∩ …``."""

    __slots__ = ("base", "subtrahends")

    def __init__(self, base, subtrahends: Iterable) -> None:
        self.base = as_node(base)
        self.subtrahends = tuple(as_node(s) for s in subtrahends)
        if not self.subtrahends:
            raise CsgnbError("a difference needs at least one subtrahend: difference(a, b, ...)")

    def children(self) -> tuple[Node, ...]:
        return (self.base, *self.subtrahends)


class Complement(Node):
    """The complement (Boolean NOT) of its child."""

    __slots__ = ("child",)

    def __init__(self, child) -> None:
        self.child = as_node(child)

    def children(self) -> tuple[Node, ...]:
        return (self.child,)


class Transformed(Node):
    """An edge annotated with a transform: the child mapped by ``matrix`` (``x ↦ M x``).

    ``matrix`` : (4, 4) float64, affine or projective and invertible; a (3, 4) ``[R | t]`` is
    completed with ``(0, 0, 0, 1)``. NaN/inf entries or a singular matrix raise
    :class:`GeometryError` here, when the edge is built.
    """

    __slots__ = ("child", "matrix")

    def __init__(self, child, matrix) -> None:
        self.child = as_node(child)
        m = as_matrix(matrix, "transform").copy()
        transform_inverse(m, "transform (a CSG edge)")  # refuses singular maps here, where the edge is built
        m.setflags(write=False)
        self.matrix = m

    def children(self) -> tuple[Node, ...]:
        return (self.child,)

    def _label(self) -> str:
        return "Transformed"


# -- constructors -------------------------------------------------------------------------------


def as_node(obj) -> Node:
    """Return ``obj`` as a node: nodes pass through, a :class:`Quadric` becomes a :class:`Leaf`."""
    if isinstance(obj, Node):
        return obj
    if isinstance(obj, Quadric):
        return Leaf(obj)
    raise TypeError(f"expected a csgnb.csg Node or a Quadric, got {type(obj).__name__}")


def leaf(quadric: Quadric, name: str | None = None) -> Leaf:
    """Return a leaf for ``quadric`` (the solid where Q ≤ 0)."""
    return Leaf(quadric, name)


def _flat(kind, operands) -> list[Node]:
    out: list[Node] = []
    for o in operands:
        n = as_node(o)
        # nested operations of the same kind are merged (variadic), shared nodes are kept as they are
        out.extend(n.operands if type(n) is kind else (n,))
    return out


def union(*operands) -> Union:
    """Return the union of ``operands`` (nodes or quadrics; nested unions are flattened)."""
    return Union(_flat(Union, operands))


def intersection(*operands) -> Intersection:
    """Return the intersection of ``operands`` (nodes or quadrics; nested ones are flattened)."""
    return Intersection(_flat(Intersection, operands))


def difference(base, *subtrahends) -> Difference:
    """Return ``base`` minus each of ``subtrahends``."""
    return Difference(base, subtrahends)


def complement(operand) -> Complement:
    """Return the complement of ``operand``."""
    return Complement(operand)


def transformed(operand, matrix) -> Transformed:
    """Return ``operand`` mapped by the 4×4 ``matrix`` (an annotated edge)."""
    return Transformed(operand, matrix)


def rotation_matrix(axis, angle: float, center=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Return the 4×4 rotation by ``angle`` (radians) about ``axis`` : (3,) through ``center``."""
    a = _finite(axis, (3,), "axis")
    n = float(np.linalg.norm(a))
    if n == 0.0:
        raise GeometryError("rotation axis is zero; pass a non-zero direction")
    a = a / n
    angle = as_real(angle, "angle")
    c, s = np.cos(angle), np.sin(angle)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    R = np.eye(3) + s * K + (1.0 - c) * (K @ K)
    ctr = _finite(center, (3,), "center")
    m = np.eye(4)
    m[:3, :3] = R
    m[:3, 3] = ctr - R @ ctr
    return m


# -- inspection -------------------------------------------------------------------------------


def _walk(root: Node) -> Iterator[Node]:
    seen: set[int] = set()
    stack = [as_node(root)]
    while stack:
        n = stack.pop()
        if id(n) in seen:
            continue
        seen.add(id(n))
        yield n
        stack.extend(reversed(n.children()))


def _leaf_paths(root: Node, M: np.ndarray | None = None) -> Iterator[tuple[Leaf, np.ndarray | None]]:
    """Each distinct (leaf, path map) pair of the graph once: the transforms along the path from the root composed
    (``M`` applied at the root first; None where no map is on the path), in a depth-first order."""
    seen: set[tuple[int, bytes | None]] = set()
    stack: list[tuple[Node, np.ndarray | None]] = [(as_node(root), M)]
    while stack:
        node, P = stack.pop()
        key = (id(node), None if P is None else P.tobytes())
        if key in seen:
            continue
        seen.add(key)
        if isinstance(node, Leaf):
            yield node, P
        elif isinstance(node, Transformed):
            stack.append((node.child, node.matrix if P is None else P @ node.matrix))
        else:
            stack.extend((c, P) for c in node.children())


def graph_leaves(root: Node) -> list[Leaf]:
    """Return the distinct leaves of the graph (a shared leaf once)."""
    return [n for n in _walk(root) if isinstance(n, Leaf)]


def graph_size(root: Node) -> int:
    """Return the number of distinct nodes of the graph (shared sub-graphs count once)."""
    return sum(1 for _ in _walk(root))
