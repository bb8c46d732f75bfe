"""The contact settings a run plan writes on a top's geoms and pairs, and how MuJoCo mixes them.

Every colliding geom of the top and of the static world (the table), and every explicit contact
pair of the top, is one :class:`ContactSetting` of the plan. MuJoCo makes a contact's condim,
friction, solref and solimp from the two geoms' (:func:`mix`, its ``mj_contactParam``), or takes
an explicit pair's as they are; :func:`ball_table_contact` is the ball's contact with the table.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

#: The roles of a plan's contact elements.
ROLES = ("ball", "stem", "table", "pair")
#: MuJoCo's smallest solmix that counts (``mjMINVAL``).
_MINVAL = 1e-15
#: MuJoCo's smallest friction coefficient in a contact (``mjMINMU``).
_MINMU = 1e-5


@dataclass(frozen=True)
class ContactSetting:
    """The contact parameters of one colliding geom or contact pair, as the plan writes them.

    Attributes:
        element: ``geom`` or ``pair``.
        index: The geom's (pair's) id in the compiled model: its place in the document.
        name: The geom's name (``#id`` if it has none); a pair's geoms' names.
        role: ``ball``, ``stem`` (another colliding geom of the top: the stem, say), ``table``
            (a colliding geom of the static world) or ``pair``.
        condim: Contact dimensionality.
        friction: A geom's (sliding, torsional m, rolling m); a pair's five coefficients.
        solref: (time constant s, damping ratio), or (-stiffness, -damping).
        solimp: (d0, dwidth, width m, midpoint, power).
        contype: A geom's contact type bits (a pair: 0).
        conaffinity: A geom's contact affinity bits (a pair: 0).
        priority: A geom's contact priority (a pair: 0).
        solmix: A geom's solver mixing weight (a pair: 1).
        geoms: A pair's two geom ids; () for a geom.
        solreffriction: A pair's own solref of its friction rows; () where it has none (a
            geom, or a pair's [0, 0]: its friction rows use solref).
    """

    element: str
    index: int
    name: str
    role: str
    condim: int
    friction: tuple[float, ...]
    solref: tuple[float, ...]
    solimp: tuple[float, ...]
    contype: int = 0
    conaffinity: int = 0
    priority: int = 0
    solmix: float = 1.0
    geoms: tuple[int, ...] = ()
    solreffriction: tuple[float, ...] = ()

    @property
    def collides(self) -> bool:
        """A pair always; a geom with any contact type or affinity bit."""
        return self.element == "pair" or bool(self.contype or self.conaffinity)

    def with_values(self, *, condim: int | None = None, mu: float | None = None,
                    torsional: float | None = None, rolling: float | None = None,
                    solref: Sequence[float] | None = None,
                    solimp: Sequence[float] | None = None) -> ContactSetting:
        """This setting with the values given (None keeps its own).

        A geom's friction is (mu, torsional, rolling); a pair's (mu, mu, torsional, rolling,
        rolling). A solimp of three numbers replaces the first three.
        """
        fr = list(self.friction)
        slots = ({"mu": (0,), "torsional": (1,), "rolling": (2,)} if self.element == "geom"
                 else {"mu": (0, 1), "torsional": (2,), "rolling": (3, 4)})
        for key, value in (("mu", mu), ("torsional", torsional), ("rolling", rolling)):
            if value is not None:
                for i in slots[key]:
                    fr[i] = float(value)
        imp = list(self.solimp)
        if solimp is not None:
            imp[:len(solimp)] = [float(v) for v in solimp]
        return replace(self, condim=self.condim if condim is None else int(condim),
                       friction=tuple(fr),
                       solref=self.solref if solref is None else tuple(float(v) for v in solref),
                       solimp=tuple(imp))

    def to_attributes(self) -> dict[str, str]:
        """MJCF attributes of the element (numbers at full precision)."""
        from tippetop.models.mjcf_document import fmt

        out = {"condim": str(self.condim), "friction": fmt(self.friction),
               "solref": fmt(self.solref), "solimp": fmt(self.solimp)}
        if self.element == "geom":
            out.update(contype=str(self.contype), conaffinity=str(self.conaffinity))
        elif self.solreffriction:
            out["solreffriction"] = fmt(self.solreffriction)
        return out


@dataclass(frozen=True)
class MixedContact:
    """The parameters of a contact between two geoms, as MuJoCo makes them.

    Attributes:
        condim: Contact dimensionality.
        friction: The five coefficients (sliding twice, torsional, rolling twice), as mixed
            (MuJoCo's contact holds each at least ``mjMINMU``: :attr:`contact_friction`).
        solref: (time constant s, damping ratio), or (-stiffness, -damping).
        solimp: (d0, dwidth, width m, midpoint, power).
        source: Which elements gave them (``geoms ball and table``, ``pair ball table``).
        solreffriction: The friction rows' own solref (a pair's); () where they use solref.
    """

    condim: int
    friction: tuple[float, ...]
    solref: tuple[float, ...]
    solimp: tuple[float, ...]
    source: str
    solreffriction: tuple[float, ...] = ()

    @property
    def contact_friction(self) -> tuple[float, ...]:
        """The five coefficients as MuJoCo's contact holds them: each at least ``mjMINMU``."""
        return tuple(max(_MINMU, f) for f in self.friction)

    def acting(self) -> dict[str, Any]:
        """condim, and the coefficients it uses (None where it has no friction row).

        The keys and values of a summary's ``what ran`` (read from MuJoCo's contact):
        ``condim``, ``mu``, ``torsional``, ``rolling``, ``solref``, ``solreffriction`` (None
        where the friction rows use solref), ``solimp``.
        """
        c, f = self.condim, self.contact_friction
        return {"condim": c, "mu": f[0] if c >= 3 else None,
                "torsional": f[2] if c >= 4 else None, "rolling": f[3] if c >= 6 else None,
                "solref": list(self.solref),
                "solreffriction": list(self.solreffriction) if self.solreffriction else None,
                "solimp": list(self.solimp)}


def mix(a: ContactSetting, b: ContactSetting) -> MixedContact:
    """The contact of geoms ``a`` and ``b``: MuJoCo's ``mj_contactParam``.

    The geom of higher priority gives everything; at equal priority condim and friction are
    the larger of the two, solref and solimp their solmix-weighted mean (solref the smaller of
    each when either is given directly, negative).
    """
    if a.priority != b.priority:
        g = a if a.priority > b.priority else b
        condim, fri = g.condim, g.friction
        solref, solimp = g.solref, g.solimp
    else:
        condim = max(a.condim, b.condim)
        s1, s2 = a.solmix, b.solmix
        if s1 >= _MINVAL and s2 >= _MINVAL:
            w = s1 / (s1 + s2)
        elif s1 < _MINVAL and s2 < _MINVAL:
            w = 0.5
        else:
            w = 0.0 if s1 < _MINVAL else 1.0
        if a.solref[0] > 0 and b.solref[0] > 0:
            solref = tuple(w * x + (1 - w) * y for x, y in zip(a.solref, b.solref, strict=True))
        else:
            solref = tuple(min(x, y) for x, y in zip(a.solref, b.solref, strict=True))
        solimp = tuple(w * x + (1 - w) * y for x, y in zip(a.solimp, b.solimp, strict=True))
        fri = tuple(max(x, y) for x, y in zip(a.friction, b.friction, strict=True))
    return MixedContact(condim, (fri[0], fri[0], fri[1], fri[2], fri[2]), tuple(solref),
                        tuple(solimp), f"geoms {a.name} and {b.name}")


def _can_collide(a: ContactSetting, b: ContactSetting) -> bool:
    return bool(a.contype & b.conaffinity or b.contype & a.conaffinity)


def with_friction_pairs(contacts: Sequence[ContactSetting], solreffriction: Sequence[float],
                        first_index: int) -> tuple[ContactSetting, ...]:
    """``contacts`` with the friction rows' own solref on a pair for every top-table contact.

    MuJoCo takes ``solreffriction`` only on an explicit ``<pair>`` (and only in an elliptic
    cone). The top's pairs get it; every colliding geom of the top (ball, stem) and table geom
    it can collide with that no pair covers gets a new pair (ids from ``first_index``, the
    model's pair count), with the values MuJoCo would mix for the two geoms: the contact is
    the same but for its friction rows' solref.
    """
    srf = tuple(float(v) for v in solreffriction)
    out = [replace(c, solreffriction=srf) if c.element == "pair" else c for c in contacts]
    covered = {frozenset(c.geoms) for c in contacts if c.element == "pair"}
    tables = [c for c in contacts if c.role == "table"]
    index = first_index
    for g in contacts:
        if g.element != "geom" or g.role not in ("ball", "stem") or not g.collides:
            continue
        for t in tables:
            if not _can_collide(g, t) or frozenset((g.index, t.index)) in covered:
                continue
            m = mix(t, g)
            out.append(ContactSetting("pair", index, f"{g.name} {t.name}", "pair", m.condim,
                                      m.friction, m.solref, m.solimp, geoms=(g.index, t.index),
                                      solreffriction=srf))
            index += 1
    return tuple(out)


def ball_table_contact(contacts: Sequence[ContactSetting]) -> MixedContact | None:
    """The ball's contact with the table: an explicit pair's, else the two geoms' mixed.

    The table is the first static geom the ball can collide with. None: the ball touches no
    static geom.
    """
    ball = next((c for c in contacts if c.role == "ball"), None)
    if ball is None:
        return None
    tables = {c.index: c for c in contacts if c.role == "table"}
    for c in contacts:
        if c.element == "pair" and ball.index in c.geoms and any(g in tables for g in c.geoms):
            return MixedContact(c.condim, c.friction, c.solref, c.solimp, f"pair {c.name}",
                                c.solreffriction)
    for table in tables.values():
        if _can_collide(ball, table):
            return mix(table, ball)
    return None


__all__ = ["ROLES", "ContactSetting", "MixedContact", "ball_table_contact", "mix",
           "with_friction_pairs"]
