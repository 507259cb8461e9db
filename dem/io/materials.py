"""Materials of a scene file: particle groups, walls of their own material, and the
:class:`dem.ContactModel` they make.

A scene's particles belong to groups (``[particles] group``, default ``"particles"``;
``[insert] group``, default the same); every wall, plane (``[[walls]]``) or triangle mesh
(``[[meshes]]``), belongs to the group ``"walls"``. The
contact law is one ``[contact]`` table for every pair of groups, or an array of
``[[contact]]`` tables, each naming its ``pair`` of groups (``pair = ["sand", "walls"]``
is the law between the sand and every wall). A ``[[walls]]`` or ``[[meshes]]`` table may
give the wall its own material: the keys of the particle-wall law that it names replace those of the
law of its pair, the rest are kept. For ``hertz_mindlin`` a wall's ``young`` and
``poisson`` are the wall's side of the pair (the particles' side keeps the ``[contact]``
values) and ``rigid = true`` makes it rigid (``1/E`` of the wall is 0 in ``E*`` and
``G*``); for ``linear`` the wall's ``kn``, ``kt``, ... are the contact's own.

Each group becomes a material row (``mat_id``) in the order particles, insert; walls
without material keys share one row after them, and each wall with its own material
gets its own (planes first, then meshes, in file order). A scene with one ``[contact]``
table and no wall material keeps every body on row 0 and one law for all.
"""

from dataclasses import dataclass, replace

from ..contact.laws import LAWS, law_class
from .schema import NONNEGATIVE, UNIT_OPEN_CLOSED, Key
from .text import show as _show

__all__ = ["DEFAULT_GROUP", "ROLLING_KEYS", "WALLS", "WALL_MATERIAL_KEYS", "Materials",
           "check_materials", "rolling_spec", "scene_materials", "wall_tables"]

#: the group of particles that name none
DEFAULT_GROUP = "particles"
#: the group of every wall
WALLS = "walls"

#: rolling and twisting resistance (:class:`dem.Rolling`), keys of every law's table
ROLLING_KEYS = {
    "mu_roll": Key("float", default=0.0, range=NONNEGATIVE,
                   doc="Rolling-friction coefficient: the rolling moment is capped at "
                       "mu_roll R f_n (R the effective radius); 0 with mu_twist = 0: "
                       "no rolling resistance."),
    "eta_roll": Key("float", default=0.0, range=NONNEGATIVE,
                    doc="Damping ratio of the rolling and twisting dashpots."),
    "k_roll": Key("float", range=NONNEGATIVE,
                  doc="Rolling stiffness over k_n R^2; default 2.25 mu_roll^2."),
    "mu_twist": Key("float", default=0.0, range=NONNEGATIVE,
                    doc="Twisting-friction coefficient (3D): the moment about the normal "
                        "is capped at mu_twist R f_n."),
    "k_twist": Key("float", range=NONNEGATIVE,
                   doc="Twisting stiffness over k_n R^2; default 2.25 mu_twist^2."),
}

_FALLBACK = " Default: the particle-wall [contact] value."
#: the keys every law lets a wall set for its own material
_SHARED_WALL_KEYS = {
    "mu": Key("float", range=NONNEGATIVE,
              doc="Friction coefficient between the wall and particles." + _FALLBACK),
    "restitution": Key("float", range=UNIT_OPEN_CLOSED,
                       doc="Restitution between the wall and particles." + _FALLBACK),
    "mu_roll": Key("float", range=NONNEGATIVE,
                   doc="Rolling-friction coefficient between the wall and particles."
                       + _FALLBACK),
}


def _wall_keys():
    """The keys a [[walls]] table may set for its own material, by law, and the schema
    of all of them (a law's own key names the law in its doc)."""
    by_law, keys = {}, {}
    for name, cls in LAWS.items():
        own = cls.wall_keys()
        by_law[name] = (*own, *_SHARED_WALL_KEYS)
        for key, spec in own.items():
            if key in keys:  # another law's key of the same name: name both laws
                keys[key] = replace(keys[key], doc=keys[key].doc.replace(":", f", {name}:", 1))
            else:
                fallback = "" if spec.type == "bool" else _FALLBACK
                keys[key] = replace(spec, doc=f"{name}: {spec.doc}{fallback}")
    return by_law, {**keys, **_SHARED_WALL_KEYS}


#: WALL_KEYS: the keys a [[walls]] table may set for its own material, by law;
#: WALL_MATERIAL_KEYS: their schema
WALL_KEYS, WALL_MATERIAL_KEYS = _wall_keys()


def rolling_spec(table):
    """The ``rolling`` argument of a law from a table with :data:`ROLLING_KEYS`: a
    :class:`dem.Rolling` spec, or None when ``mu_roll`` and ``mu_twist`` are 0."""
    if not (table.get("mu_roll") or table.get("mu_twist")):
        return None
    return {"mu_roll": table.get("mu_roll") or 0.0, "eta_roll": table.get("eta_roll") or 0.0,
            "k_roll": table.get("k_roll"), "mu_twist": table.get("mu_twist") or 0.0,
            "k_twist": table.get("k_twist")}


@dataclass(frozen=True)
class Materials:
    """The material rows of a scene: ``groups`` {group name: mat_id}, ``walls`` the
    mat_id of each wall (the ``[[walls]]`` planes, then the ``[[meshes]]``, in file
    order), ``model`` the :class:`dem.ContactModel`."""

    groups: dict
    walls: list
    model: object


# --------------------------------------------------------------------------- reading
def contact_tables(scene):
    """The ``[contact]`` table(s) of a validated scene, as a list."""
    c = scene["contact"]
    return c if isinstance(c, list) else [c]


def _where(scene, i):
    return f"[[contact]] #{i + 1}" if isinstance(scene["contact"], list) else "[contact]"


def particle_groups(scene):
    """The particle groups, in mat_id order: [particles], then a new [insert] one."""
    groups = [scene["particles"]["group"]]
    ins = scene.get("insert")
    if ins is not None and ins.get("group") is not None and ins["group"] not in groups:
        groups.append(ins["group"])
    return groups


def wall_tables(scene):
    """``(where, table)`` of every wall: the ``[[walls]]`` planes, then the
    ``[[meshes]]``."""
    return ([(f"[[walls]] #{i + 1}", w) for i, w in enumerate(scene["walls"])]
            + [(f"[[meshes]] #{i + 1}", m) for i, m in enumerate(scene.get("meshes") or [])])


def _own_keys(wall):
    """The material keys a [[walls]] table sets (``rigid = false`` is no change)."""
    return [k for k in WALL_MATERIAL_KEYS if wall.get(k) is not None and wall.get(k) is not False]


def _uniform(scene):
    """One [contact] table for every pair and no wall of its own material."""
    tables = contact_tables(scene)
    return (len(tables) == 1 and tables[0]["pair"] is None
            and not any(_own_keys(w) for _, w in wall_tables(scene)))


def _pairs(scene):
    """The group pairs the scene holds, particle-particle then particle-wall."""
    groups = particle_groups(scene)
    pp = [(a, b) for i, a in enumerate(groups) for b in groups[i:]]
    pw = [(a, WALLS) for a in groups] if wall_tables(scene) else []
    return pp, pw


def _table_for(scene, a, b):
    """(index, table) of the [contact] table acting between groups a and b, or None."""
    for i, t in enumerate(contact_tables(scene)):
        if t["pair"] is None or sorted(t["pair"]) == sorted((a, b)):
            return i, t
    return None


# --------------------------------------------------------------------------- checks
def check_materials(ctx, scene):
    """Cross checks of groups, [[contact]] pairs and wall materials (one line each)."""
    tables = contact_tables(scene)
    if not tables:
        ctx.fail("needs at least one table", "[[contact]]")
    groups = particle_groups(scene)
    if WALLS in groups:
        which = "[particles]" if scene["particles"]["group"] == WALLS else "[insert]"
        ctx.fail(f'group must not be "{WALLS}", the name of the walls\' group', which)
    _check_pairs(ctx, scene, groups)
    pp, pw = _pairs(scene)
    for a, b in pp + pw:
        if _table_for(scene, a, b) is None:
            ctx.fail(f"no law for the group pair {_show([a, b])} that the scene holds "
                     f"(add a [[contact]] table with pair = {_show([a, b])})",
                     "[[contact]]")
    for bucket, pairs in (("particle-particle", pp), ("particle-wall", pw)):
        used = sorted({_table_for(scene, a, b)[0] for a, b in pairs})
        for i in used[1:]:
            if tables[i]["law"] != tables[used[0]]["law"]:
                ctx.fail(f'law = "{tables[i]["law"]}" differs from law = '
                         f'"{tables[used[0]]["law"]}" of #{used[0] + 1}: every '
                         f"{bucket} pair needs the same law (one compiled loop per kind "
                         f"of contact)", _where(scene, i))
    if pw:
        _check_walls(ctx, scene, tables[_table_for(scene, *pw[0])[0]]["law"])


def _check_pairs(ctx, scene, groups):
    tables = contact_tables(scene)
    seen = {}
    for i, t in enumerate(tables):
        where = _where(scene, i)
        if t["pair"] is None:
            if len(tables) > 1:
                ctx.fail("missing required key 'pair' (each of several [[contact]] "
                         "tables names the two groups it acts between)", where)
            continue
        for name in t["pair"]:
            if name not in groups and name != WALLS:
                known = _show(groups + [WALLS])
                ctx.fail(f'pair names the group "{name}", which no [particles] or '
                         f"[insert] defines (groups: {known})", where)
        if t["pair"] == [WALLS, WALLS]:
            ctx.fail("pair: walls do not touch walls", where)
        key = tuple(sorted(t["pair"]))
        if key in seen:
            ctx.fail(f"pair = {_show(t['pair'])} repeats that of #{seen[key] + 1}", where)
        seen[key] = i


def _check_walls(ctx, scene, law):
    for where, w in wall_tables(scene):
        for key in _own_keys(w):
            if key not in WALL_KEYS[law]:
                ctx.fail(f'{key} is not used with the {law} law of particle-wall '
                         f"contacts (a wall takes {', '.join(WALL_KEYS[law])})", where)
        if w.get("rigid") and w.get("young") is not None:
            ctx.fail("rigid = true and young exclude each other (a rigid wall has no "
                     "Young's modulus)", where)


# --------------------------------------------------------------------------- building
def _law(table, where, ctx, **own):
    """The law of a [contact] table, with a wall's own keys replacing its values."""
    try:
        return law_class(table["law"]).from_table(
            table, own, rolling=rolling_spec({**table, **{k: v for k, v in own.items()
                                                         if v is not None}}))
    except ValueError as exc:
        ctx.fail(str(exc), where)


def scene_materials(ctx, scene):
    """The :class:`Materials` of a validated scene (see the module docstring)."""
    from ..contact.model import ContactModel

    groups = particle_groups(scene)
    tables = wall_tables(scene)
    walls = [w for _, w in tables]
    if _uniform(scene):
        law = _law(contact_tables(scene)[0], "[contact]", ctx)
        return Materials({g: 0 for g in groups}, [0] * len(walls), ContactModel(law))
    ids = {g: k for k, g in enumerate(groups)}
    nxt = len(groups)
    shared = nxt if any(not _own_keys(w) for w in walls) else None
    nxt += shared is not None
    wall_ids = []
    for w in walls:
        wall_ids.append(nxt if _own_keys(w) else shared)
        nxt += bool(_own_keys(w))
    pp, pw = {}, {}
    for a, b in _pairs(scene)[0]:
        i, t = _table_for(scene, a, b)
        pp[(ids[a], ids[b])] = _law(t, _where(scene, i), ctx)
    for g in groups:
        for k, w in enumerate(walls):
            if (ids[g], wall_ids[k]) in pw:
                continue
            i, t = _table_for(scene, g, WALLS)
            own = {key: w[key] for key in _own_keys(w)}
            where = tables[k][0] if own else _where(scene, i)
            pw[(ids[g], wall_ids[k])] = _law(t, where, ctx, **own)
    return Materials(ids, wall_ids, ContactModel(pp, pw or None))
