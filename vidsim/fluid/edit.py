"""The edit configuration: sources, sinks, desired flow distribution, constraints, obstacles
and external forces, validated from a YAML-style dict and rasterised onto the edit grid.

Coordinates are grid nodes: ``x`` is the column (0 at the left), ``y`` the row (0 at the
top, growing downward). Boxes are ``[x0, y0, x1, y1]`` with the end exclusive, like Python
slices. Velocities are grid nodes per frame. See ``docs/fluid_editing.md`` for the format.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.ndimage import label as cc_label


class EditSpecError(ValueError):
    """An invalid edit configuration; the message names the key and the value."""


Box = tuple[int, int, int, int]


def _keys(d: Any, where: str, allowed: set[str], required: set[str] = frozenset()) -> dict:
    if not isinstance(d, dict):
        raise EditSpecError(f"{where}: expected a mapping, got {type(d).__name__} {d!r}")
    unknown = sorted(set(map(str, d)) - allowed)
    if unknown:
        raise EditSpecError(f"{where}: unknown key(s) {unknown}; allowed keys are {sorted(allowed)}")
    missing = sorted(required - set(d))
    if missing:
        raise EditSpecError(f"{where}: missing required key(s) {missing}")
    return d


def _box(v: Any, where: str, h: int, w: int) -> Box:
    if not (isinstance(v, (list, tuple)) and len(v) == 4 and all(isinstance(a, (int, np.integer)) for a in v)):
        raise EditSpecError(f"{where}: expected [x0, y0, x1, y1] integers, got {v!r}")
    x0, y0, x1, y1 = (int(a) for a in v)
    if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
        raise EditSpecError(
            f"{where}={list(v)} lies outside the {w}x{h} grid or is empty "
            f"(expected 0 <= x0 < x1 <= {w}, 0 <= y0 < y1 <= {h})")
    return (x0, y0, x1, y1)


def _vec(v: Any, where: str) -> tuple[float, float]:
    if not (isinstance(v, (list, tuple)) and len(v) == 2 and all(isinstance(a, (int, float)) for a in v)):
        raise EditSpecError(f"{where}: expected [x, y] numbers, got {v!r}")
    if not all(np.isfinite(v)):
        raise EditSpecError(f"{where}={v!r} is not finite")
    return (float(v[0]), float(v[1]))


def _pos(v: Any, where: str, lo: float, hi: float) -> float:
    if not isinstance(v, (int, float)) or not (lo <= v <= hi):
        raise EditSpecError(f"{where}={v!r}, expected a number in [{lo}, {hi}]")
    return float(v)


@dataclass(frozen=True)
class Sink:
    """A sink: particles entering its box terminate there."""

    name: str
    box: Box


@dataclass(frozen=True)
class Source:
    """A source box; each node emits one particle. ``distribution`` lists (sink, fraction)
    in order along the box's longer side (left to right, or top to bottom)."""

    name: str
    box: Box
    distribution: tuple[tuple[str, float], ...]
    velocity: tuple[float, float] | None = None


@dataclass(frozen=True)
class Obstacle:
    """A collision object: a box ``[x0,y0,x1,y1]`` or an ellipse (center, radii); zero velocity.
    ``in_footage``: the solid is in the footage at this place (a PIV recording's cylinder), so the
    render shows the footage's own pixels there and takes no fluid texture from it; otherwise it
    is added by the edit and rendered (``render.added_obstacles``) as the appearance of an
    ``in_footage`` obstacle mapped onto its shape (:meth:`EditSpec.transplant_sources`), or from
    velocity-matched patches (solid texture if the footage has an ``in_footage`` obstacle)."""

    box: Box | None = None
    center: tuple[float, float] | None = None
    radii: tuple[float, float] | None = None
    in_footage: bool = False

    def mask(self, h: int, w: int) -> np.ndarray:
        """``(h, w)`` bool: the grid nodes this obstacle covers."""
        if self.box is not None:
            m = np.zeros((h, w), bool)
            x0, y0, x1, y1 = self.box
            m[y0:y1, x0:x1] = True
            return m
        yy, xx = np.mgrid[0:h, 0:w]
        return ((xx - self.center[0]) / self.radii[0]) ** 2 + ((yy - self.center[1]) / self.radii[1]) ** 2 <= 1.0

    def extent(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """Centre ``(x, y)`` and half-size ``(x, y)`` in nodes of the area the obstacle's node cells
        cover (each node a cell one node wide): a box ``[x0, y0, x1, y1]`` has centre
        ``((x0 + x1 - 1) / 2, (y0 + y1 - 1) / 2)`` and half-size ``((x1 - x0) / 2, (y1 - y0) / 2)``;
        an ellipse its ``center`` and ``radii + 1/2`` (the cells of its rim nodes reach half a
        node past it)."""
        if self.box is not None:
            x0, y0, x1, y1 = self.box
            return ((x0 + x1 - 1) / 2, (y0 + y1 - 1) / 2), ((x1 - x0) / 2, (y1 - y0) / 2)
        return self.center, (self.radii[0] + 0.5, self.radii[1] + 0.5)


@dataclass(frozen=True)
class Constraint:
    """A hard velocity constraint: ``paste`` copies the video field from box ``src`` to the box
    of equal size at ``dst`` (top-left corner); ``stroke`` sets nodes within ``width`` of a
    polyline to its tangent times ``speed``."""

    kind: str
    src: Box | None = None
    dst: tuple[int, int] | None = None
    points: tuple[tuple[float, float], ...] = ()
    speed: float = 1.0
    width: float = 1.0


@dataclass(frozen=True)
class Force:
    """An external acceleration (nodes/frame^2) acting for ``duration`` frames on a box: the
    edited field there is matched to the video's velocity neighbourhoods shifted by a*duration."""

    box: Box
    acceleration: tuple[float, float]
    duration: float = 1.0


@dataclass(frozen=True)
class Weights:
    """Objective weights alpha (flow), beta (smoothness), gamma (neighbourhood), eq. 17."""

    flow: float = 1.0
    smooth: float = 0.2
    neighborhood: float = 0.2


@dataclass(frozen=True)
class OptimizerSettings:
    """Gradient descent settings (eq. 32 with an adaptive step)."""

    iterations: int = 150
    step: float = 0.5
    init: str = "harmonic"  # harmonic | video | uniform
    trace_step: float = 0.5
    uniform: tuple[float, float] = (0.0, 1.0)


@dataclass(frozen=True)
class RenderSettings:
    """Texture-transfer settings (seed 5.4): patch side and overlap in output pixels, K nearest
    velocity patches, output frames, ``mode`` "advected" (patches move with the edited field)
    or "fixed" (each output patch keeps its source patch and plays the source in time);
    ``velocity_noise`` (px/frame): velocity-patch differences below it are ties, and K more
    candidates are drawn at random within it (0: K nearest only); ``usage``: weight of
    uniform use of the source (0: off); ``blend``: "linear" feathering, "variance"
    (contrast-preserving, for stochastic textures such as PIV particles) or "multiband" (the
    coarse band feathered, the fine band from each pixel's owner patch alone); ``resample``:
    "cubic" (Catmull-Rom) or "linear" sampling of sub-pixel source positions;
    ``added_obstacles``: "transplant" (an obstacle the edit adds shows the footage's temporal
    median of an ``in_footage`` obstacle, mapped onto its shape; patches without one) or
    "patches" (texture patches, solid texture if the footage has an ``in_footage`` obstacle)."""

    patch: int = 12
    overlap: int = 4
    k: int = 8
    frames: int = 120
    mode: str = "advected"
    seed: int = 0
    velocity_noise: float = 0.03
    usage: float = 1.0
    blend: str = "linear"
    resample: str = "cubic"
    added_obstacles: str = "transplant"


@dataclass(frozen=True)
class EditProblem:
    """Rasterised edit on a ``(H, W)`` grid.

    Attributes:
        particles: ``(M, 2)`` float source-node positions (x, y).
        desired: ``(M,)`` int desired sink index per particle.
        sink_id: ``(H, W)`` int sink index per node, -1 elsewhere.
        sink_boxes: ``(N, 4)`` float ``[x0, y0, x1-1, y1-1]`` node extents of the sinks.
        solid: ``(H, W)`` bool obstacle nodes.
        fixed: ``(H, W)`` bool nodes with a hard velocity (obstacles and constraints).
        fixed_value: ``(H, W, 2)`` their velocities.
        offset: ``(H, W, 2)`` external-force velocity offsets.
        source_speed: ``(M,)`` desired particle speed at the source (nan if free).
    """

    particles: np.ndarray
    desired: np.ndarray
    sink_id: np.ndarray
    sink_boxes: np.ndarray
    solid: np.ndarray
    fixed: np.ndarray
    fixed_value: np.ndarray
    offset: np.ndarray
    sink_names: tuple[str, ...]


@dataclass(frozen=True)
class EditSpec:
    """A validated edit; build it with :meth:`from_dict`."""

    height: int
    width: int
    sources: tuple[Source, ...]
    sinks: tuple[Sink, ...]
    obstacles: tuple[Obstacle, ...] = ()
    constraints: tuple[Constraint, ...] = ()
    forces: tuple[Force, ...] = ()
    weights: Weights = field(default_factory=Weights)
    optimizer: OptimizerSettings = field(default_factory=OptimizerSettings)
    footage: str = ""
    downsample: int = 1
    description: str = ""
    render: RenderSettings = field(default_factory=RenderSettings)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "EditSpec":
        """Validate a YAML-style dict (see ``docs/fluid_editing.md``).

        Raises:
            EditSpecError: unknown or missing keys, boxes outside the grid, overlapping sinks,
                fractions that do not sum to 1, a distribution naming an unknown sink, or a
                source from which its sinks cannot be reached around the obstacles.
        """
        _keys(d, "edit", {"grid", "sources", "sinks", "obstacles", "constraints", "forces", "weights",
                          "optimizer", "footage", "downsample", "description", "render"}, {"grid", "sources", "sinks"})
        g = _keys(d["grid"], "grid", {"height", "width"}, {"height", "width"})
        h, w = g["height"], g["width"]
        for k, v in (("grid.height", h), ("grid.width", w)):
            if not isinstance(v, int) or not 8 <= v <= 4096:
                raise EditSpecError(f"{k}={v!r}, expected an integer in [8, 4096]")
        sinks = []
        if not isinstance(d["sinks"], list) or not d["sinks"]:
            raise EditSpecError(f"sinks: expected a non-empty list, got {d['sinks']!r}")
        for i, s in enumerate(d["sinks"]):
            _keys(s, f"sinks[{i}]", {"name", "box"}, {"name", "box"})
            sinks.append(Sink(str(s["name"]), _box(s["box"], f"sinks[{i}].box", h, w)))
        names = [s.name for s in sinks]
        if len(set(names)) != len(names):
            raise EditSpecError(f"sinks: duplicate names in {names}")
        # a node in two sinks would belong to the later one only (rasterize overwrites sink_id),
        # so a particle could never end in the earlier sink there: refuse the overlap by name
        for i, a in enumerate(sinks):
            for j in range(i + 1, len(sinks)):
                b = sinks[j]
                ox0, oy0 = max(a.box[0], b.box[0]), max(a.box[1], b.box[1])
                ox1, oy1 = min(a.box[2], b.box[2]), min(a.box[3], b.box[3])
                if ox0 < ox1 and oy0 < oy1:
                    raise EditSpecError(
                        f"sinks[{i}] ({a.name!r}, box {list(a.box)}) and sinks[{j}] ({b.name!r}, box {list(b.box)}) "
                        f"overlap in [{ox0}, {oy0}, {ox1}, {oy1}]: sinks must be disjoint")
        sources = []
        if not isinstance(d["sources"], list) or not d["sources"]:
            raise EditSpecError(f"sources: expected a non-empty list, got {d['sources']!r}")
        for i, s in enumerate(d["sources"]):
            where = f"sources[{i}]"
            _keys(s, where, {"name", "box", "distribution", "velocity"}, {"box", "distribution"})
            box = _box(s["box"], f"{where}.box", h, w)
            dist = s["distribution"]
            if isinstance(dist, str):
                dist = [[dist, 1.0]]
            if not isinstance(dist, list) or not dist:
                raise EditSpecError(f"{where}.distribution: expected a sink name or [[sink, fraction], ...], got {dist!r}")
            pairs = []
            for j, p in enumerate(dist):
                if not (isinstance(p, (list, tuple)) and len(p) == 2):
                    raise EditSpecError(f"{where}.distribution[{j}]={p!r}, expected [sink, fraction]")
                if p[0] not in names:
                    raise EditSpecError(f"{where}.distribution[{j}] names sink {p[0]!r}; known sinks are {names}")
                pairs.append((str(p[0]), _pos(p[1], f"{where}.distribution[{j}].fraction", 0.0, 1.0)))
            tot = sum(f for _, f in pairs)
            if abs(tot - 1.0) > 1e-6:
                raise EditSpecError(f"{where}.distribution fractions sum to {tot}, expected 1")
            vel = _vec(s["velocity"], f"{where}.velocity") if "velocity" in s else None
            sources.append(Source(str(s.get("name", f"source{i}")), box, tuple(pairs), vel))
        obstacles = []
        for i, o in enumerate(d.get("obstacles", []) or []):
            where = f"obstacles[{i}]"
            _keys(o, where, {"box", "center", "radii", "in_footage"})
            inf = o.get("in_footage", False)
            if not isinstance(inf, bool):
                raise EditSpecError(f"{where}.in_footage={inf!r}, expected true or false")
            if "box" in o:
                obstacles.append(Obstacle(box=_box(o["box"], f"{where}.box", h, w), in_footage=inf))
            elif "center" in o and "radii" in o:
                c = _vec(o["center"], f"{where}.center")
                r = _vec(o["radii"], f"{where}.radii")
                if not (0 <= c[0] < w and 0 <= c[1] < h) or min(r) <= 0:
                    raise EditSpecError(f"{where}: center {c} must lie inside the {w}x{h} grid and radii {r} be > 0")
                obstacles.append(Obstacle(center=c, radii=r, in_footage=inf))
            else:
                raise EditSpecError(f"{where}: expected either 'box' or both 'center' and 'radii'")
        constraints = []
        for i, c in enumerate(d.get("constraints", []) or []):
            where = f"constraints[{i}]"
            _keys(c, where, {"paste", "stroke"})
            if len(c) != 1:
                raise EditSpecError(f"{where}: expected exactly one of 'paste' or 'stroke', got {sorted(c)}")
            if "paste" in c:
                p = _keys(c["paste"], f"{where}.paste", {"from", "to"}, {"from", "to"})
                src = _box(p["from"], f"{where}.paste.from", h, w)
                to = p["to"]
                if not (isinstance(to, (list, tuple)) and len(to) == 2 and all(isinstance(a, int) for a in to)):
                    raise EditSpecError(f"{where}.paste.to: expected [x, y] integers, got {to!r}")
                bw, bh = src[2] - src[0], src[3] - src[1]
                _box([to[0], to[1], to[0] + bw, to[1] + bh], f"{where}.paste.to (pasted box)", h, w)
                constraints.append(Constraint("paste", src=src, dst=(int(to[0]), int(to[1]))))
            else:
                p = _keys(c["stroke"], f"{where}.stroke", {"points", "speed", "width"}, {"points"})
                pts = p["points"]
                if not isinstance(pts, list) or len(pts) < 2:
                    raise EditSpecError(f"{where}.stroke.points: expected >= 2 [x, y] points, got {pts!r}")
                pts_t = tuple(_vec(q, f"{where}.stroke.points[{j}]") for j, q in enumerate(pts))
                for j, (x, y) in enumerate(pts_t):
                    if not (0 <= x <= w - 1 and 0 <= y <= h - 1):
                        raise EditSpecError(f"{where}.stroke.points[{j}]={[x, y]} lies outside the {w}x{h} grid")
                constraints.append(Constraint(
                    "stroke", points=pts_t, speed=_pos(p.get("speed", 1.0), f"{where}.stroke.speed", 0.0, 100.0),
                    width=_pos(p.get("width", 1.0), f"{where}.stroke.width", 0.0, 1000.0)))
        forces = []
        for i, f in enumerate(d.get("forces", []) or []):
            where = f"forces[{i}]"
            _keys(f, where, {"box", "acceleration", "duration"}, {"box", "acceleration"})
            forces.append(Force(_box(f["box"], f"{where}.box", h, w), _vec(f["acceleration"], f"{where}.acceleration"),
                                _pos(f.get("duration", 1.0), f"{where}.duration", 0.0, 1e4)))
        wd = _keys(d.get("weights", {}) or {}, "weights", {"flow", "smooth", "neighborhood"})
        weights = Weights(**{k: _pos(v, f"weights.{k}", 0.0, 1e6) for k, v in wd.items()})
        od = _keys(d.get("optimizer", {}) or {}, "optimizer", {"iterations", "step", "init", "trace_step", "uniform"})
        if "init" in od and od["init"] not in ("harmonic", "video", "uniform"):
            raise EditSpecError(f"optimizer.init={od['init']!r}, expected 'harmonic', 'video' or 'uniform'")
        if "iterations" in od and (not isinstance(od["iterations"], int) or od["iterations"] < 0):
            raise EditSpecError(f"optimizer.iterations={od['iterations']!r}, expected an integer >= 0")
        opt = OptimizerSettings(
            iterations=int(od.get("iterations", OptimizerSettings.iterations)),
            step=_pos(od.get("step", OptimizerSettings.step), "optimizer.step", 1e-9, 1e6),
            init=str(od.get("init", "harmonic")),
            trace_step=_pos(od.get("trace_step", 0.5), "optimizer.trace_step", 0.05, 1.0),
            uniform=_vec(od.get("uniform", [0.0, 1.0]), "optimizer.uniform"))
        ds = d.get("downsample", 1)
        if not isinstance(ds, int) or ds < 1:
            raise EditSpecError(f"downsample={ds!r}, expected an integer >= 1")
        rd = dict(_keys(d.get("render", {}) or {}, "render", {"patch", "overlap", "k", "frames", "mode", "seed",
                                                               "velocity_noise", "usage", "blend", "resample",
                                                               "added_obstacles"}))
        for key, lo in (("patch", 4), ("overlap", 0), ("k", 1), ("frames", 1), ("seed", 0)):
            if key in rd and (not isinstance(rd[key], int) or rd[key] < lo):
                raise EditSpecError(f"render.{key}={rd[key]!r}, expected an integer >= {lo}")
        for key in ("velocity_noise", "usage"):
            if key in rd:
                rd[key] = _pos(rd[key], f"render.{key}", 0.0, 10.0)
        for key, allowed in (("mode", ("advected", "fixed")), ("blend", ("linear", "variance", "multiband")),
                             ("resample", ("cubic", "linear")), ("added_obstacles", ("transplant", "patches"))):
            if key in rd and rd[key] not in allowed:
                raise EditSpecError(f"render.{key}={rd[key]!r}, expected one of {list(allowed)}")
        rs = RenderSettings(**rd)
        if rs.overlap * 2 >= rs.patch:
            raise EditSpecError(f"render.overlap={rs.overlap}, expected < patch/2 = {rs.patch / 2}")
        spec = cls(h, w, tuple(sources), tuple(sinks), tuple(obstacles), tuple(constraints), tuple(forces),
                   weights, opt, str(d.get("footage", "")), ds, str(d.get("description", "")), rs)
        spec._check_reachable()
        return spec

    def solid_mask(self, in_footage: bool | None = None) -> np.ndarray:
        """``(H, W)`` bool obstacle nodes; ``in_footage`` True/False: only the obstacles that are
        / are not in the footage (None: all)."""
        solid = np.zeros((self.height, self.width), bool)
        for o in self.obstacles:
            if in_footage is None or o.in_footage == in_footage:
                solid |= o.mask(self.height, self.width)
        return solid

    def transplant_sources(self) -> tuple[int | None, ...]:
        """Per obstacle, the index of the ``in_footage`` obstacle whose appearance an added
        obstacle is drawn with (``render.added_obstacles: transplant``); None for the
        ``in_footage`` obstacles themselves and for every obstacle when none is declared
        ``in_footage``. The rule: among the ``in_footage`` obstacles of the same kind (ellipse or
        box; any kind if there is none), the least deformation, the smallest
        ``|log sx| + |log sy|`` of the per-axis scale between the two half-sizes
        (:meth:`Obstacle.extent`), so the closest in size and aspect; ties go to the first declared."""
        shown = [i for i, o in enumerate(self.obstacles) if o.in_footage]
        out: list[int | None] = []
        for o in self.obstacles:
            if o.in_footage or not shown:
                out.append(None)
                continue
            same = [i for i in shown if (self.obstacles[i].box is None) == (o.box is None)] or shown
            half = o.extent()[1]

            def deformation(i: int) -> float:
                hs = self.obstacles[i].extent()[1]
                return abs(np.log(hs[0] / half[0])) + abs(np.log(hs[1] / half[1]))
            out.append(min(same, key=deformation))
        return tuple(out)

    def _check_reachable(self) -> None:
        solid = self.solid_mask()
        lab, _ = cc_label(~solid)
        for s in self.sinks:
            x0, y0, x1, y1 = s.box
            if solid[y0:y1, x0:x1].all():
                raise EditSpecError(f"sink {s.name!r} box {list(s.box)} lies entirely inside an obstacle")
        for i, src in enumerate(self.sources):
            x0, y0, x1, y1 = src.box
            comps = set(lab[y0:y1, x0:x1][~solid[y0:y1, x0:x1]].ravel()) - {0}
            if not comps:
                raise EditSpecError(f"sources[{i}] ({src.name!r}) box {list(src.box)} lies entirely inside an obstacle")
            for sname, frac in src.distribution:
                if frac == 0:
                    continue
                sk = next(s for s in self.sinks if s.name == sname)
                a0, b0, a1, b1 = sk.box
                if not comps & set(lab[b0:b1, a0:a1].ravel()):
                    raise EditSpecError(
                        f"sources[{i}] ({src.name!r}): sink {sname!r} cannot be reached from the source; "
                        "obstacles wall it off")

    def rasterize(self, video_field: np.ndarray | None = None) -> EditProblem:
        """Turn the edit into arrays on the grid.

        Args:
            video_field: ``(H, W, 2)`` velocity field of the video at grid resolution (needed
                for ``paste`` constraints).
        """
        h, w = self.height, self.width
        solid = self.solid_mask()
        names = tuple(s.name for s in self.sinks)
        sink_id = -np.ones((h, w), np.int64)
        boxes = []
        for k, s in enumerate(self.sinks):
            x0, y0, x1, y1 = s.box
            sink_id[y0:y1, x0:x1] = np.where(solid[y0:y1, x0:x1], -1, k)
            boxes.append([x0, y0, x1 - 1, y1 - 1])
        fixed = solid.copy()
        fixed_value = np.zeros((h, w, 2))
        parts, desired = [], []
        for src in self.sources:
            x0, y0, x1, y1 = src.box
            ys, xs = np.mgrid[y0:y1, x0:x1]
            if (x1 - x0) >= (y1 - y0):
                order = np.lexsort((ys.ravel(), xs.ravel()))
            else:
                order = np.lexsort((xs.ravel(), ys.ravel()))
            pts = np.stack([xs.ravel()[order], ys.ravel()[order]], 1).astype(float)
            keep = ~solid[pts[:, 1].astype(int), pts[:, 0].astype(int)]
            pts = pts[keep]
            m = len(pts)
            edges = np.rint(np.cumsum([0.0] + [f for _, f in src.distribution]) * m).astype(int)
            lab = np.empty(m, np.int64)
            for (sname, _), a, b in zip(src.distribution, edges[:-1], edges[1:]):
                lab[a:b] = names.index(sname)
            parts.append(pts)
            desired.append(lab)
            if src.velocity is not None:
                fixed[y0:y1, x0:x1] = True
                fixed_value[y0:y1, x0:x1] = src.velocity
        for c in self.constraints:
            if c.kind == "paste":
                if video_field is None:
                    raise EditSpecError("constraints: a 'paste' constraint needs the video velocity field")
                if video_field.shape != (h, w, 2):
                    raise EditSpecError(f"video_field shape {video_field.shape}, expected {(h, w, 2)}")
                x0, y0, x1, y1 = c.src
                tx, ty = c.dst
                fixed[ty:ty + y1 - y0, tx:tx + x1 - x0] = True
                fixed_value[ty:ty + y1 - y0, tx:tx + x1 - x0] = video_field[y0:y1, x0:x1]
            else:
                yy, xx = np.mgrid[0:h, 0:w]
                P = np.array(c.points)
                for a, b in zip(P[:-1], P[1:]):
                    t = b - a
                    L = np.linalg.norm(t)
                    if L == 0:
                        continue
                    s = np.clip(((xx - a[0]) * t[0] + (yy - a[1]) * t[1]) / L**2, 0, 1)
                    dist = np.hypot(xx - a[0] - s * t[0], yy - a[1] - s * t[1])
                    sel = (dist <= c.width) & ~solid
                    fixed[sel] = True
                    fixed_value[sel] = t / L * c.speed
        offset = np.zeros((h, w, 2))
        for f in self.forces:
            x0, y0, x1, y1 = f.box
            offset[y0:y1, x0:x1] += np.array(f.acceleration) * f.duration
        fixed_value[solid] = 0.0
        return EditProblem(np.concatenate(parts), np.concatenate(desired), sink_id, np.array(boxes, float),
                           solid, fixed, fixed_value, offset, names)
