"""The geometry of the mesh-anchored patches against independent references (docs/physics.md
(M1)-(M4)): shapely for polygon clipping, pieces and boolean differences, the image method traced
point by point for the chains' regions, and segment-plane intersections for the occluders'
shadows. Every check runs on faces oblique to every axis, from antennas at two look angles and
off the track's zero heading.

Deliberate bugs these tests were run against (each fails at least one of them):
  * :func:`clip` keeping the entering crossing point but dropping the leaving one;
  * :func:`moments` with the ``Ixy`` weights of ``Ixx`` (``x0 y1 + 2 x0 y0 ...`` swapped);
  * :func:`pieces_of` marking patches whole from the region's extent on one of the row's lines
    instead of both;
  * :func:`region_lines` without the "last window crossed before the point" half-plane (a bug
    these tests found: chains seen from behind their last window lit regions for discovery);
  * :func:`shadow_lines` on the return leg in the unfolded frame (not the real one);
  * :func:`boundary` keeping two coincident cut-out edges with the cut-outs on opposite sides
    (they cancel: two shadows that meet).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from sarmitsuba.scene.loader import shape_frame
from sarmitsuba.tracing.discovery.chains import region_lines, unfold
from sarmitsuba.tracing.mesh.facets import mesh_parts
from sarmitsuba.tracing.visibility.occlusion import boundary, lit_boundary, shadow_lines
from sarmitsuba.tracing.mesh.patches import surfaces_from
from sarmitsuba.tracing.mesh.piece_cuts import pieces_of
from sarmitsuba.tracing.mesh.polygons import clip, edge_lines, inside, moments, pad


# --------------------------------------------------------------------------- helpers
def convex(rng, centre=(0.0, 0.0), scale=1.0, k=8) -> np.ndarray:
    """A random convex polygon (counter-clockwise corners [m, 2]): the hull of ``k`` points."""
    hull = shapely.convex_hull(shapely.MultiPoint(rng.normal(size=(k, 2)) * scale + np.asarray(centre)))
    corners = np.array(hull.exterior.coords)[:-1]
    return corners if shapely.LinearRing(corners).is_ccw else corners[::-1]


def batch(polygons: list, width: int = 8) -> tuple[np.ndarray, np.ndarray]:
    poly = np.zeros((len(polygons), width, 2))
    count = np.array([len(p) for p in polygons], np.int64)
    for i, p in enumerate(polygons):
        poly[i, :len(p)] = p
    return pad(poly, count), count


def half_plane(a: float, b: float, c: float, big: float = 1e4) -> shapely.Polygon:
    """``a x + b y + c >= 0`` as a large shapely polygon."""
    n = np.array([a, b]) / math.hypot(a, b)
    p0 = -c / math.hypot(a, b) * n
    t = np.array([-n[1], n[0]])
    return shapely.Polygon([p0 - big * t, p0 + big * t, p0 + big * t + big * n, p0 - big * t + big * n])


def quad(centre, e1, e2):
    c, e1, e2 = (np.asarray(x, float) for x in (centre, e1, e2))
    return np.array([c - e1 - e2, c + e1 - e2, c + e1 + e2, c - e1 + e2]), np.array([[0, 1, 2], [0, 2, 3]])


def surfaces(meshes):
    parts = mesh_parts(meshes)
    frames = [shape_frame(np.asarray(v, float)) for v, _ in meshes]
    return surfaces_from(parts, np.arange(len(meshes)), np.ones(len(meshes), bool), np.array([f[0] for f in frames]),
                         np.array([f[1] for f in frames]), np.zeros(len(meshes), np.int64))


def reflect(p, n, c):
    return p - 2.0 * (n @ p - c) * n


def scene(rng):
    """Ground, a wall, and two small plates tilted off every axis (with a random offset)."""
    return surfaces([quad((0, 0, 0), (10, 0, 0), (0, 10, 0)),
                     quad((0, -2, 3), (6, 0, 0), (0, 0, 3)),
                     quad(np.array([1, 3, 4.0]) + rng.normal(size=3) * 0.5, (1.5, 0.5, 0.3), (0.0, 1.0, 1.0)),
                     quad(np.array([-2, 1, 2.0]) + rng.normal(size=3) * 0.5, (1.0, 0.2, 0.3), (0.3, 0.8, 0.9))])


def corner(rng):
    """A trihedral corner of three 2 m squares turned off the axes: its chains of three mirrors
    cross the windows in an order that matters."""
    turn = np.linalg.qr(rng.normal(size=(3, 3)))[0] * 0.15 + np.eye(3)
    turn = np.linalg.qr(turn)[0]
    turn *= np.sign(np.diag(turn))
    axes = [turn[:, 0], turn[:, 1], turn[:, 2]]
    return surfaces([quad(axes[a] + axes[b], axes[a], axes[b]) for a, b in ((0, 1), (1, 2), (2, 0))])


def antennas(rng):
    """Antennas at 30 and 60 deg look, 1 km away, on headings off the axes (x offset random)."""
    out = []
    for look, heading in ((30.0, 20.0), (60.0, -35.0)):
        h = math.radians(heading)
        ground = np.array([math.sin(h), math.cos(h), 0.0]) * 1000 * math.sin(math.radians(look))
        out.append(ground + np.array([rng.uniform(-20, 20), 0.0, 1000 * math.cos(math.radians(look))]))
    return out


def all_chains(s, depth: int = 3):
    n = s.n_parts
    seqs = [(a,) for a in range(n)] + [(a, b) for a in range(n) for b in range(n) if a != b]
    seqs += [(a, b, c) for a in range(n) for b in range(n) for c in range(n) if a != b and b != c]
    parts = np.full((len(seqs), depth), -1)
    for i, q in enumerate(seqs):
        parts[i, :len(q)] = q
    order = np.array([len(q) - 1 for q in seqs])
    return seqs, unfold(s, parts, order, np.zeros(len(seqs), np.int64))


def path_by_images(s, seq, x, antenna):
    """The path antenna -> seq[0] -> ... -> x by the image method (images of the antenna in
    each mirror, then back from ``x`` toward each image): its points, or None where a leg misses
    its window, and whether the antenna sees ``x``'s side from which the wave arrives."""
    images = [antenna]
    for part in seq[:-1]:
        images.append(reflect(images[-1], s.normal[part], s.offset[part]))
    points, cur = [x], x
    for i in range(len(seq) - 2, -1, -1):
        n, c = s.normal[seq[i]], s.offset[seq[i]]
        src = images[i + 1]
        den = n @ (src - cur)
        if abs(den) < 1e-15:
            return None, False
        t = (c - n @ cur) / den
        if not 1e-9 < t < 1 - 1e-9:
            return None, False
        cur = cur + t * (src - cur)
        window = shapely.Polygon(s.polygon[seq[i]][:s.n_corners[seq[i]]])
        if not window.buffer(1e-9).contains(shapely.Point(s.to_face(np.array(seq[i]), cur))):
            return None, False
        points.insert(0, cur)
    n, c = s.normal[seq[-1]], s.offset[seq[-1]]
    returns = np.sign(n @ antenna - c) == np.sign(n @ images[-1] - c)
    return [antenna] + points, returns


def crosses(s, a, b, part) -> bool:
    """The open segment a-b crosses the part (plane crossing inside its polygon)."""
    n, c = s.normal[part], s.offset[part]
    da, db = n @ a - c, n @ b - c
    if da * db >= 0:
        return False
    x = a + da / (da - db) * (b - a)
    return shapely.Polygon(s.polygon[part][:s.n_corners[part]]).contains(shapely.Point(s.to_face(np.array(part), x)))


# --------------------------------------------------------------------------- polygons
def test_clip_and_moments_match_shapely():
    """Random convex polygons cut by three random half-planes: area, centroid and second moments
    of :func:`clip` then :func:`moments` against shapely's intersection (and its coordinates)."""
    rng = np.random.default_rng(0)
    polygons = [convex(rng, scale=rng.uniform(0.1, 3)) for _ in range(400)]
    poly, count = batch(polygons)
    lines = rng.normal(size=(len(polygons), 3, 3))
    lines[:, :, 2] *= 0.5
    cut, cut_count = clip(poly, count, lines)
    area, centroid, second, _ = moments(cut, cut_count)
    nonempty = 0
    for i, p in enumerate(polygons):
        ref = shapely.Polygon(p)
        for a, b, c in lines[i]:
            ref = ref.intersection(half_plane(a, b, c))
        assert area[i] == pytest.approx(ref.area, abs=1e-9)
        if ref.area > 1e-6:
            nonempty += 1
            assert np.allclose(centroid[i], ref.centroid.coords[0], atol=1e-8)
            xy = np.array(shapely.geometry.polygon.orient(ref, 1.0).exterior.coords)
            x0, y0, x1, y1 = xy[:-1, 0], xy[:-1, 1], xy[1:, 0], xy[1:, 1]
            cross = x0 * y1 - x1 * y0
            ixy = np.sum((x0 * y1 + 2 * x0 * y0 + 2 * x1 * y1 + x1 * y0) * cross) / 24 - ref.area * ref.centroid.x * ref.centroid.y
            ixx = np.sum((x0 * x0 + x0 * x1 + x1 * x1) * cross) / 12 - ref.area * ref.centroid.x ** 2
            assert second[i, 0] == pytest.approx(ixx, abs=1e-7) and second[i, 1] == pytest.approx(ixy, abs=1e-7)
    assert nonempty > 100                                 # the cuts leave something to compare


def test_pieces_are_the_patches_of_the_region():
    """:func:`pieces_of` against shapely: every piece is its patch intersected with its region
    (whole pieces exactly the patch), no patch that meets a region is missing, and the pieces of a
    region add up to its area. Regions of every size against the patch, far from the frame's
    origin too."""
    rng = np.random.default_rng(1)
    polygons = [convex(rng, centre=rng.normal(size=2) * 10 + (200.0 if i % 5 == 0 else 0.0),
                       scale=rng.uniform(0.3, 6)) for i in range(150)]
    poly, count = batch(polygons)
    patch = 1.3
    pieces = pieces_of(poly, count, patch)
    area, _, _, _ = pieces.geometry()
    for r, p in enumerate(polygons):
        region = shapely.Polygon(p)
        rows = np.flatnonzero(pieces.region == r)
        assert area[rows].sum() == pytest.approx(region.area, rel=1e-9)
        small = np.all(p.max(axis=0) - p.min(axis=0) <= patch)
        if small:                                          # a region within a patch's size is one piece
            assert len(rows) == 1
            continue
        seen = set()
        for k in rows:
            i, j = pieces.cell[k]
            seen.add((i, j))
            ref = shapely.box(i * patch, j * patch, (i + 1) * patch, (j + 1) * patch).intersection(region)
            assert area[k] == pytest.approx(ref.area, abs=1e-9)
            assert not pieces.whole[k] or ref.area == pytest.approx(patch * patch, rel=1e-9)
        lo, hi = np.floor(p.min(axis=0) / patch).astype(int), np.floor(p.max(axis=0) / patch).astype(int)
        for i in range(lo[0], hi[0] + 1):
            for j in range(lo[1], hi[1] + 1):
                meets = shapely.box(i * patch, j * patch, (i + 1) * patch, (j + 1) * patch).intersection(region).area
                assert meets < 1e-9 or (i, j) in seen


# --------------------------------------------------------------------------- chains
@pytest.mark.parametrize("seed, layout", [(3, scene), (4, scene), (5, corner)])
def test_chain_regions_are_the_image_method(seed, layout):
    """For every chain of up to three parts of an oblique scene and a turned trihedral corner,
    the region :func:`region_lines` cuts on its last part holds exactly the points the image
    method reaches through the chain's windows (points within 1e-6 m of the region's edge
    skipped)."""
    rng = np.random.default_rng(seed)
    s = layout(rng)
    seqs, chains = all_chains(s)
    tested = reached = 0
    for antenna in antennas(rng):
        lines, valid, returns = region_lines(s, chains, np.repeat(antenna[None], len(seqs), 0))
        region, region_count = clip(s.polygon[chains.last], s.n_corners[chains.last], lines)
        for i, seq in enumerate(seqs):
            face = s.polygon[seq[-1]][:s.n_corners[seq[-1]]]
            cut = shapely.Polygon(region[i][:region_count[i]]) if region_count[i] >= 3 and valid[i] else None
            for p2 in rng.uniform(face.min(0), face.max(0), size=(60, 2)):
                point = shapely.Point(p2)
                if not shapely.Polygon(face).contains(point) or (cut is not None and cut.exterior.distance(point) < 1e-6):
                    continue
                path, back = path_by_images(s, seq, s.to_world(np.array(seq[-1]), p2), antenna)
                inside_region = cut is not None and cut.contains(point)
                assert (path is not None) == inside_region, (seq, p2)
                if inside_region:
                    assert bool(returns[i]) == bool(back)
                tested += 1
                reached += path is not None
    assert tested > 1000 and reached > 100


def test_shadow_lines_are_the_occluders_on_each_leg():
    """The half-planes of :func:`shadow_lines` hold exactly the points whose path (by the image
    method) through a chain crosses the occluder on the named leg, the return leg included."""
    rng = np.random.default_rng(11)
    s = scene(rng)
    seqs, chains = all_chains(s)
    depth = chains.parts.shape[1]
    tested = hidden = 0
    for antenna in antennas(rng):
        region, valid, _ = region_lines(s, chains, np.repeat(antenna[None], len(seqs), 0))
        for i, seq in enumerate(seqs):
            if len(seq) == 3 and rng.random() < 0.5:            # a sample of the third order (the test's time)
                continue
            d = len(seq) - 1
            face = s.polygon[seq[-1]][:s.n_corners[seq[-1]]]
            points = rng.uniform(face.min(0) - 1, face.max(0) + 1, size=(40, 2))
            held = (inside(points[None], region[i:i + 1])[0] & valid[i]
                    & inside(points[None], edge_lines(s.polygon[seq[-1]][None], s.n_corners[seq[-1]][None]))[0])
            for occluder in set(range(s.n_parts)) - set(seq):
                for leg in list(range(d + 1)) + ([depth] if d > 0 else []):
                    lines = shadow_lines(s, chains, np.array([i]), np.array([occluder]), np.array([leg]), antenna[None])
                    shadowed = inside(points[None], lines)[0]
                    for k in np.flatnonzero(held):
                        path, _ = path_by_images(s, seq, s.to_world(np.array(seq[-1]), points[k]), antenna)
                        if path is None:
                            continue
                        a, b = (path[-1], antenna) if leg == depth or (d == 0 and leg == 0) else (path[leg], path[leg + 1])
                        truth = crosses(s, a, b, occluder)
                        assert truth == shadowed[k], (seq, occluder, leg)
                        tested += 1
                        hidden += truth
    assert tested > 1000 and hidden > 20


# --------------------------------------------------------------------------- exact clipping
@pytest.mark.parametrize("flat", [False, True], ids=["padded", "flat"])
def test_lit_boundary_is_the_piece_less_its_cut_outs(flat):
    """:func:`boundary` (cut-outs padded per piece) and :func:`lit_boundary` (one flat list, the
    fast kernel) of a piece less overlapping, adjacent and edge-sharing cut-outs: the area, first
    and second moments their segments give by Green's theorem against shapely's difference."""
    rng = np.random.default_rng(7)
    groups, n_cut = 300, 4
    bases, cuts = [], []
    for g in range(groups):
        base = np.array([[0, 0], [1.7, 0], [1.7, 1.7], [0, 1.7]]) if g % 3 == 0 else convex(rng, k=7)
        b_all, bc_all = batch([base])
        b, bc = b_all[0], int(bc_all[0])
        mine = []
        for i in range(int(rng.integers(1, n_cut + 1))):
            kind = rng.integers(0, 3)
            if kind == 0:                                  # a shadow's half-plane: shares the piece's edges
                angle = rng.uniform(0, 2 * np.pi)
                line = np.array([[[math.cos(angle), math.sin(angle), rng.normal() * 0.3]]])
            elif kind == 1 and mine:                       # adjacent to the last cut-out: a shared edge
                p0, p1 = mine[-1][0], mine[-1][1]
                out = np.array([p1[1] - p0[1], -(p1[0] - p0[0])])
                c = np.array([p1, p0, p0 + out * 0.5, p1 + out * 0.5])
                line = None
            else:
                c, line = convex(rng, centre=rng.normal(size=2) * 0.6, scale=0.4), None
            if line is None:
                poly_c, count_c = batch([c], 16)
                poly_c, count_c = clip(poly_c, count_c, edge_lines(b[None], np.array([bc])))
            else:
                poly_c, count_c = clip(b[None], np.array([bc]), line)
            if count_c[0] >= 3:
                mine.append(poly_c[0][:count_c[0]])
        bases.append(base)
        cuts.append(mine)
    base_poly, base_count = batch(bases)
    cut = np.zeros((groups, n_cut, 16, 2))
    cut_count = np.zeros((groups, n_cut), np.int64)
    for g, mine in enumerate(cuts):
        for i, c in enumerate(mine):
            cut[g, i, :len(c)] = c
            cut_count[g, i] = len(c)
            pad(cut[g, i:i + 1], cut_count[g, i:i + 1])
    if flat:
        has = cut_count > 0
        owner, p, q = lit_boundary(base_poly, base_count, cut[has], cut_count[has], np.nonzero(has)[0])
        # no cut-out at all: each piece's own edges
        o0, p0, q0 = lit_boundary(base_poly, base_count, cut[has][:0], cut_count[has][:0], np.zeros(0, np.int64))
        assert np.bincount(o0, weights=p0[:, 0] * q0[:, 1] - q0[:, 0] * p0[:, 1], minlength=groups) / 2 == \
            pytest.approx(moments(base_poly, base_count)[0], abs=1e-12)
    else:
        owner, p, q = boundary(base_poly, base_count, cut, cut_count)
    for g in range(groups):
        lit = shapely.Polygon(bases[g]).difference(shapely.unary_union([shapely.Polygon(c) for c in cuts[g]]
                                                                       or [shapely.Polygon()]))
        m = owner == g
        cross = p[m, 0] * q[m, 1] - q[m, 0] * p[m, 1]
        area = 0.5 * cross.sum()
        assert area == pytest.approx(lit.area, abs=1e-9)
        if lit.area > 1e-6:
            cx = np.sum((p[m, 0] + q[m, 0]) * cross) / (6 * area)
            assert cx == pytest.approx(lit.centroid.x, abs=1e-7)
        ixx = np.sum((p[m, 0] ** 2 + p[m, 0] * q[m, 0] + q[m, 0] ** 2) * cross) / 12
        ref = 0.0
        for poly in getattr(lit, "geoms", [lit]):
            poly = shapely.geometry.polygon.orient(poly, 1.0)
            for ring in [poly.exterior, *poly.interiors]:
                xy = np.array(ring.coords)
                x0, y0, x1, y1 = xy[:-1, 0], xy[:-1, 1], xy[1:, 0], xy[1:, 1]
                ref += np.sum((x0 * x0 + x0 * x1 + x1 * x1) * (x0 * y1 - x1 * y0)) / 12
        assert ixx == pytest.approx(ref, abs=1e-8)


def test_occluder_partners_are_the_faces_a_part_meets():
    """A box turned 25 deg and a separate plate with a corner on one of the box's: each face of
    the box has for partners the four faces it shares an edge with, never the opposite face nor
    the plate (corners of one shape only); the plate has only its own parts. The graph of a box's
    faces is the octahedron's."""
    import trimesh
    from sarmitsuba.tracing.mesh.patches import occluder_partners
    box = trimesh.creation.box((4.0, 3.0, 2.0))
    box.apply_transform(trimesh.transformations.rotation_matrix(math.radians(25), (0, 0, 1)))
    corner = box.vertices[np.argmax(box.vertices.sum(axis=1))]
    plate = quad(corner + (0.5, 0.5, 0.0), (0.5, 0.0, 0.0), (0.0, 0.5, 0.0))     # one corner on the box's
    s = surfaces([(box.vertices, box.faces), plate])
    start, partners = occluder_partners(s)
    plate_parts = np.flatnonzero(s.shape_id == 1)
    box_parts = np.flatnonzero((s.shape_id == 0) & (s.n_corners > 0))
    faces = np.unique(s.face[box_parts])
    assert len(faces) == 6
    for part in plate_parts:
        assert not set(partners[start[part]:start[part + 1]].tolist()) - set(plate_parts.tolist())
    for face in faces:
        mine = np.concatenate([partners[start[p]:start[p + 1]] for p in box_parts[s.face[box_parts] == face]])
        assert set(mine.tolist()) <= set(box_parts.tolist())
        met = set(s.face[mine].tolist()) - {face}
        normal = s.normal[box_parts[s.face[box_parts] == face][0]]
        opposite = {f for f in faces if np.dot(s.normal[box_parts[s.face[box_parts] == f][0]], normal) < -0.99}
        assert len(met) == 4 and not met & opposite


# --------------------------------------------------------------------------- moving boundaries
def test_boundary_rates_are_the_regions_cut_again():
    """eq. (M8): the rates :func:`motion.endpoint_rates` gives the corners of chain regions less an
    occluder's shadow (ground, wall and two tilted plates; first and second bounce; two antennas
    at 30 and 60 deg look on headings 20 and -35 deg, moving along their track) equal the corners
    of the same regions cut again, from the antenna 1 mm further on, by finite difference (a
    second method), within 1e-3 m per m. Covers corners on a moving and a fixed line (they slide
    along the face's edge) and on two moving lines (a shadow's tip, a mirror's image corner).
    Deliberate bugs: the right-hand side's sign flipped; a corner on a fixed line taken as fixed.
    (polygons.clip must not rewrite its input's corners: the second cut would start from the
    first's polygon.)"""
    from sarmitsuba.tracing.visibility.motion import endpoint_rates, line_rates
    rng = np.random.default_rng(5)
    s = scene(rng)
    seqs, chains = all_chains(s)
    step = 1e-3
    tested = both_moving = 0
    for antenna in antennas(rng):
        track = np.array([antenna[1], -antenna[0], 0.0])
        track /= np.linalg.norm(track)
        for i, seq in enumerate(seqs):
            if len(seq) > 2:
                continue
            for occluder in sorted(set(range(s.n_parts)) - set(seq)):
                if abs(s.normal[occluder] @ s.normal[seq[-1]]) > 0.999:
                    continue                # a part of the same plane: its shadow's edge is its own edge
                cuts = []
                for position in (antenna, antenna + step * track):
                    region = region_lines(s, chains.select(np.array([i])), position[None])[0]
                    shadow = shadow_lines(s, chains, np.array([i]), np.array([occluder]), np.array([0]), position[None])
                    # the lit region less the shadow's strip beyond one of its lines: a convex clip
                    cuts.append(np.concatenate([region, -shadow[:, 3:4]], axis=1))
                face = pad(s.polygon[seq[-1]][None], s.n_corners[seq[-1]][None])
                (p0, n0), (p1, n1) = (clip(face, s.n_corners[seq[-1]][None], c) for c in cuts)
                if n0[0] < 3 or n0[0] != n1[0] or np.abs(p1[0, :n0[0]] - p0[0, :n0[0]]).max() > 0.01 * step:
                    continue
                truth = (p1[0, :n0[0]] - p0[0, :n0[0]]) / step
                corners = p0[0, :n0[0]]
                start, end = corners, np.roll(corners, -1, axis=0)
                static = edge_lines(face, s.n_corners[seq[-1]][None])[0]
                lines = np.concatenate([static, cuts[0][0]])
                rates = np.concatenate([np.zeros_like(static), line_rates(cuts[0][0][None], cuts[1][0][None], np.array([step]))[0]])
                got, got_end = endpoint_rates(start, end, np.zeros(len(start), np.int64), np.zeros(len(lines), np.int64),
                                              lines, rates)
                moving = np.abs(truth).max(axis=1) > 1e-6
                assert np.allclose(got, truth, atol=1e-3), (seq, occluder, got, truth)
                assert np.allclose(np.roll(got_end, 1, axis=0), truth, atol=1e-3)
                tested += int(moving.sum())
                on_moving = np.abs(np.einsum("hi,vi->vh", cuts[0][0][:, :2], corners) + cuts[0][0][:, 2]) < 1e-7
                both_moving += int(np.sum(on_moving.sum(axis=1) >= 2))
    assert tested > 30 and both_moving > 5, (tested, both_moving)


def test_unique_pairs_are_numpys_unique_rows():
    """:func:`unique_pairs` against ``np.unique(..., axis=0)`` on pairs with repeats, negative
    second members (the -2 of a non-mesh occluder) and a wide range; a negative first raises."""
    from sarmitsuba.core.arrays import unique_pairs
    rng = np.random.default_rng(3)
    first = rng.integers(0, 50, 4000)
    second = np.where(rng.random(4000) < 0.1, -2, rng.integers(0, 10 ** 6, 4000))
    first = np.concatenate([first, first[:500]])
    second = np.concatenate([second, second[:500]])
    expected = np.unique(np.stack([first, second], axis=1), axis=0)
    np.testing.assert_array_equal(unique_pairs(first, second), expected)
    assert unique_pairs(np.zeros(0, np.int64), np.zeros(0, np.int64)).shape == (0, 2)
    with pytest.raises(ValueError, match="first"):
        unique_pairs(np.array([-1]), np.array([0]))


def test_occluders_in_a_legs_own_planes_hide_nothing():
    """:func:`in_leg_planes` against the geometry: ground (two coplanar halves, separate shapes),
    a wall standing on it and a roof above. For the double bounce wall -> ground (legs 0: antenna
    -> wall, 1: wall -> ground, 2 = D: ground -> antenna) the parts lying in the plane a leg starts
    or ends on are exactly: the wall on legs 0 and 1, both ground halves on legs 1 and 2; the roof
    never, the wall never on the return. The first bounce on the wall: the wall on leg 0 only. A
    part 1 cm off the wall's plane (parallel) is not in it."""
    from sarmitsuba.tracing.visibility.lit_pieces import in_leg_planes
    s = surfaces([quad((-5, 0, 0), (5, 0, 0), (0, 10, 0)), quad((5, 0, 0), (5, 0, 0), (0, 10, 0)),
                  quad((0, -2, 3), (6, 0, 0), (0, 0, 3)), quad((0, -1, 6), (6, 0, 0), (0, 1, 0)),
                  quad((0, -2.01, 3), (1, 0, 0), (0, 0, 1))])
    part = {k: int(np.flatnonzero((s.shape_id == k) & (s.n_corners > 0))[0]) for k in range(5)}
    ground_a, ground_b, wall, roof, near = (part[k] for k in range(5))
    depth = 3
    parts = np.full((2, depth), -1)
    parts[0, :2] = (wall, ground_a)
    parts[1, 0] = wall
    chains = unfold(s, parts, np.array([1, 0]), np.zeros(2, np.int64))
    cases, expected = [], []
    for leg in (0, 1, depth):
        for occ, truth in ((wall, leg in (0, 1)), (ground_a, leg in (1, depth)), (ground_b, leg in (1, depth)),
                           (roof, False), (near, False)):
            cases.append((0, leg * s.n_parts + occ))
            expected.append(truth)
    for leg, occ, truth in ((0, wall, True), (0, ground_a, False), (0, roof, False), (depth, wall, True)):
        cases.append((1, leg * s.n_parts + occ))
        expected.append(truth if leg == 0 else True)         # first bounce: its return leg starts on the wall
    cases.append((0, -1))
    expected.append(False)
    chain, key = np.array(cases).T
    np.testing.assert_array_equal(in_leg_planes(s, chains, chain, key), np.array(expected))
