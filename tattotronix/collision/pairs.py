"""Which body pairs are checked: the allowed (never checked) pairs are derived, not typed.

The bodies are the arm's links with geometry, plus the environment: the bench and the panel,
fixed to the world, to which ``base_link`` is fixed too. A pair is **allowed** (like an
SRDF's disabled pair) only when

* the two bodies are **rigidly attached**: the tree path between them has no movable
  joint (``tool_mount_link`` and the pen; ``base_link`` and the bench); or
* they are **neighbours through one joint**: the path has exactly one movable joint and
  passes only through shape-less frames. The joint's hinge holds the two together at
  every angle, so their meshes touch by design and can never separate.

Every other pair is checked. On the TATTOTRONIX tree this gives the original's 6 allowed
pairs of the 21 link pairs (docs/original.md, "Allowed collision pairs").
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

from tattotronix.robot.description import RobotDescription

__all__ = ["ENVIRONMENT", "LIMB", "ON_SKIN", "WORLD", "BodyPair", "body_pairs"]

WORLD = "world"
#: environment bodies, fixed to the world (bench top at z = 0; the panel on it)
ENVIRONMENT = ("bench", "panel")
#: the limb a drawing on a curved surface goes on (issue 33), in the panel's place
LIMB = "limb"
#: the environment of a drawing on the limb
ON_SKIN = ("bench", LIMB)


@dataclass(frozen=True)
class BodyPair:
    """Two bodies and whether their collisions are checked.

    Attributes:
        a, b: body names (links, ``bench``, ``panel`` or ``limb``).
        checked: False for an allowed pair.
        reason: why a pair is allowed ("" for checked pairs).
        joints: the movable joints on the tree path between them.
    """

    a: str
    b: str
    checked: bool
    reason: str
    joints: tuple[str, ...]

    @property
    def environment(self) -> bool:
        """True when one body is the bench, the panel or the limb."""
        return bool({self.a, self.b} & {*ENVIRONMENT, LIMB})

    @property
    def name(self) -> str:
        """``a|b``."""
        return f"{self.a}|{self.b}"


def _parents(d: RobotDescription, environment: tuple[str, ...]
             ) -> dict[str, tuple[str, str | None]]:
    """node -> (parent, movable joint name or None) over links, frames and the world."""
    up: dict[str, tuple[str, str | None]] = {d.links[0]: (WORLD, None)}
    for j in d.joints:
        up[j.child] = (j.parent, j.name)
    for f in d.frames:
        up.setdefault(f.name, (f.parent, None))
    for env in environment:
        up[env] = (WORLD, None)
    return up


def _path(up: dict[str, tuple[str, str | None]], a: str, b: str) -> tuple[list[str], list[str]]:
    """(inner nodes, movable joints) on the tree path from ``a`` to ``b``."""
    def chain(n: str) -> list[str]:
        out = [n]
        while out[-1] in up:
            out.append(up[out[-1]][0])
        return out

    ca, cb = chain(a), chain(b)
    common = next(n for n in ca if n in cb)
    side_a, side_b = ca[:ca.index(common)], cb[:cb.index(common)]
    joints = [up[n][1] for n in side_a + side_b if up[n][1] is not None]
    inner = side_a[1:] + side_b[1:] + ([common] if common not in (a, b) else [])
    return inner, [j for j in joints if j is not None]


def body_pairs(d: RobotDescription, environment: tuple[str, ...] = ENVIRONMENT
               ) -> list[BodyPair]:
    """Every pair of bodies (links with geometry, then the environment: the bench and the
    panel, or for a drawing on the limb :data:`ON_SKIN`), classified.

    The pair of the two environment bodies is left out (neither moves); a link without
    geometry is a shape-less frame.
    """
    up = _parents(d, environment)
    shaped_links = [link for link in d.links if d.geometry.get(link)]
    bodies = set(shaped_links) | set(environment)
    out: list[BodyPair] = []
    names = shaped_links + list(environment)
    for a, b in combinations(names, 2):
        if a in environment and b in environment:
            continue
        inner, joints = _path(up, a, b)
        shaped = [n for n in inner if n in bodies]
        if not joints:
            via = " -> ".join([a, *inner, b])
            out.append(BodyPair(a, b, False, f"rigidly attached (fixed joints only: {via})",
                                ()))
        elif len(joints) == 1 and not shaped:
            out.append(BodyPair(a, b, False, f"neighbours through {joints[0]}: its hinge holds "
                                "them together at every angle", tuple(joints)))
        else:
            out.append(BodyPair(a, b, True, "", tuple(joints)))
    return out
