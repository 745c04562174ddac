//! Triangulating polygons: a convex polygon keeps the fan from its first corner (as
//! SPEC.md splits every polygon), any other is cut by ear clipping in its best-fit
//! plane, so that a concave outline (an L, a star, a ring with a notch) keeps its shape.
//!
//! The plane is Newell's: its normal is the sum of the edges' cross products, the
//! polygon's area vector, which is well defined for non-planar polygons too; the
//! corners are projected onto it and the 2D outline is clipped. Ear clipping would be
//! quadratic if every ear test looked at every corner; here only the corners that can
//! block an ear (the reflex ones) are tested, and only those in the grid cells the ear's
//! box covers, so a face of 200,000 corners takes milliseconds.

use rayon::prelude::*;

use crate::description::TriangleDesc;
use crate::math::Vec3;

/// Sine of the angle below which a turn counts as straight, whatever the rounding.
const STRAIGHT_TURN: f64 = 1e-9;

/// When a turn counts as straight: corners written on a line reach us rounded to
/// `f32`, so their turns scatter around zero, by more the farther they are from the
/// origin and the longer their edges.
#[derive(Clone, Copy)]
struct Straightness {
    /// How far a corner may be off its written place.
    rounding: f64,
}

impl Straightness {
    /// Whether the turn `a, b, c` (its value `t`, from [`turn`]) is straight: it moves
    /// `c` off the line `a, b` by no more than moving the corners by their rounding
    /// could.
    #[inline]
    fn is_straight(self, t: f64, a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> bool {
        let e1 = (b[0] - a[0]).hypot(b[1] - a[1]);
        let e2 = (c[0] - b[0]).hypot(c[1] - b[1]);
        t.abs() <= 2.0 * self.rounding * (e1 + e2) + STRAIGHT_TURN * e1 * e2
    }

    /// Whether the outline turns left at `b`, beyond rounding.
    #[inline]
    fn is_convex(self, a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> bool {
        let t = turn(a, b, c);
        t > 0.0 && !self.is_straight(t, a, b, c)
    }
}

/// How a polygon is cut into triangles.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Triangulation {
    /// The fan `(0, i, i + 1)` is right: the polygon is convex in its plane, or it has
    /// no plane (all corners on a line, or an outline whose area cancels out).
    Fan,
    /// These `corners - 2` triangles, as triples of corner indices.
    Triangles(Vec<[u32; 3]>),
}

/// Triangulates the polygon whose corners are `points`, in order (at least 3).
///
/// Convex polygons (the common case: quads) allocate nothing.
pub(crate) fn triangulate(points: &[Vec3]) -> Triangulation {
    triangulate_counting_work(points).0
}

/// [`triangulate`], and the work ear clipping did: corners tried plus k-d tree nodes
/// visited (0 for a fan). Tests hold the growth of this count far below quadratic,
/// where a clock would depend on the machine's load.
fn triangulate_counting_work(points: &[Vec3]) -> (Triangulation, u64) {
    let n = points.len();
    if n <= 3 || n > u32::MAX as usize {
        return (Triangulation::Fan, 0);
    }
    if n == 4 && is_convex_quad(points) {
        return (Triangulation::Fan, 0);
    }
    let Some(plane) = Plane::of(points) else {
        return (Triangulation::Fan, 0);
    };
    if is_convex(n, |i| plane.project(points[i])) {
        return (Triangulation::Fan, 0);
    }
    // How far the corners may be off their written place: `f32` rounding, relative to
    // the largest coordinate.
    let magnitude = points
        .iter()
        .map(|p| p.abs().max_element())
        .fold(0.0f32, f32::max);
    let straight = Straightness {
        rounding: 4.0 * f64::from(f32::EPSILON) * f64::from(magnitude),
    };
    let outline = points.iter().map(|&p| plane.project(p)).collect();
    let (triangles, work) = EarClipper::new(outline, straight).run();
    (Triangulation::Triangles(triangles), work)
}

/// A polygon of more than three corners, written as the fan of triangles from its
/// first corner: its first triangle and its corner count (the fan has `corners - 2`
/// triangles).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct FanPolygon {
    pub(crate) first: u32,
    pub(crate) corners: u32,
}

/// Polygons one parallel task cuts: enough that splitting costs little beside the
/// convexity tests of as many quads.
const POLYGONS_PER_TASK: usize = 4096;

/// Cuts again, in place and on all threads, each polygon of `polygons` (in increasing
/// order of `first`, fans that do not overlap) that is not convex: see [`recut_fan`].
/// For readers without texture coordinate indices (PLY).
pub(crate) fn recut_fans(
    positions: &[Vec3],
    triangles: &mut [TriangleDesc],
    polygons: &[FanPolygon],
) {
    let mut tasks = Vec::with_capacity(polygons.len().div_ceil(POLYGONS_PER_TASK));
    let mut rest = triangles;
    let mut at = 0usize;
    for batch in polygons.chunks(POLYGONS_PER_TASK) {
        let last = batch[batch.len() - 1];
        let end = last.first as usize + last.corners as usize - 2;
        let (part, tail) = std::mem::take(&mut rest).split_at_mut(end - at);
        tasks.push((part, at, batch));
        rest = tail;
        at = end;
    }
    tasks.into_par_iter().for_each(|(part, base, batch)| {
        for p in batch {
            let first = p.first as usize - base;
            let fan = &mut part[first..first + p.corners as usize - 2];
            recut_fan(positions, fan, None, None);
        }
    });
}

/// Cuts again, in place, the polygon whose fan is `fan` (with its triangles' normal
/// and texture coordinate indices, when kept), if it is not convex.
pub(crate) fn recut_fan(
    positions: &[Vec3],
    fan: &mut [TriangleDesc],
    normals: Option<&mut [Option<[u32; 3]>]>,
    texcoords: Option<&mut [Option<[u32; 3]>]>,
) {
    let count = fan.len() + 2;
    let index = |k: usize| {
        let (t, c) = fan_corner(k);
        fan[t].positions[c]
    };
    let point = |k: usize| positions[index(k) as usize];
    // A face with a corner that is not finite goes whole, not the fan's triangles at
    // that corner alone: each is given the corner, and `formats::finite` drops them.
    if let Some(bad) = (0..count)
        .map(index)
        .find(|&i| !positions[i as usize].is_finite())
    {
        for triangle in fan.iter_mut() {
            triangle.positions[0] = bad;
        }
        return;
    }
    // Quads, the common polygon, without an allocation.
    let triangulation = if count == 4 {
        triangulate(&[point(0), point(1), point(2), point(3)])
    } else {
        triangulate(&(0..count).map(point).collect::<Vec<_>>())
    };
    let Triangulation::Triangles(triangles) = triangulation else {
        return;
    };
    for ids in [normals, texcoords].into_iter().flatten() {
        recut_corner_ids(ids, &triangles);
    }
    let old: Vec<TriangleDesc> = fan.to_vec();
    for (slot, corners) in fan.iter_mut().zip(triangles) {
        *slot = TriangleDesc {
            positions: corners.map(|k| {
                let (t, c) = fan_corner(k as usize);
                old[t].positions[c]
            }),
            ..old[0]
        };
    }
}

/// Where corner `k` of a fan's polygon is, as (triangle, corner): corner 0 of the
/// first triangle (k = 0), corner 1 of the first (k = 1), and corner 2 of triangle
/// k - 2 (k >= 2).
fn fan_corner(k: usize) -> (usize, usize) {
    match k {
        0 => (0, 0),
        1 => (0, 1),
        k => (k - 2, 2),
    }
}

/// Gives the triangles `triangles` (corners of the polygon) the per-corner indices
/// (normals or texture coordinates) that `ids` held for the fan: a corner's index is
/// known when a triangle of the fan holding it has them all (the fan gave a triangle
/// indices only when all three corners had one).
fn recut_corner_ids(ids: &mut [Option<[u32; 3]>], triangles: &[[u32; 3]]) {
    let mut corner_ids: Vec<Option<u32>> = vec![None; ids.len() + 2];
    for (t, triangle) in ids.iter().enumerate() {
        if let Some(triangle) = triangle {
            for (c, k) in [0, t + 1, t + 2].into_iter().enumerate() {
                corner_ids[k] = Some(triangle[c]);
            }
        }
    }
    for (slot, corners) in ids.iter_mut().zip(triangles) {
        *slot = match corners.map(|k| corner_ids[k as usize]) {
            [Some(a), Some(b), Some(c)] => Some([a, b, c]),
            _ => None,
        };
    }
}

/// Whether a quad is convex in its plane, the common case, tested without the frame of
/// [`Plane`]: its Newell normal is the cross product of its diagonals, and each corner
/// must turn about it the same way (beyond [`STRAIGHT_TURN`]). `false` also for a quad
/// with no plane, which the general path then keeps as a fan.
fn is_convex_quad(points: &[Vec3]) -> bool {
    let origin = points[0].as_dvec3();
    let p = [0, 1, 2, 3].map(|i| points[i].as_dvec3() - origin);
    let normal = (p[2] - p[0]).cross(p[3] - p[1]);
    let normal_squared = normal.length_squared();
    if normal_squared == 0.0 {
        return false;
    }
    (0..4).all(|i| {
        let (e1, e2) = (p[i] - p[(i + 3) % 4], p[(i + 1) % 4] - p[i]);
        let turn = e1.cross(e2).dot(normal);
        // `turn >= -STRAIGHT_TURN |e1| |e2| |normal|`, squared.
        turn >= 0.0
            || turn * turn
                <= STRAIGHT_TURN
                    * STRAIGHT_TURN
                    * e1.length_squared()
                    * e2.length_squared()
                    * normal_squared
    })
}

/// A polygon's Newell plane, as a frame that maps its corners to 2D so that its
/// outline runs counter-clockwise (positive area).
struct Plane {
    /// The first corner: coordinates are taken relative to it, in f64, since far from
    /// the origin f32 differences of nearby corners would lose the digits that tell
    /// the turns apart.
    origin: glam::DVec3,
    u: glam::DVec3,
    v: glam::DVec3,
}

impl Plane {
    /// `None` if the polygon has no plane: its area vector is zero.
    fn of(points: &[Vec3]) -> Option<Plane> {
        let origin = points[0].as_dvec3();
        let mut normal = glam::DVec3::ZERO;
        let mut a = glam::DVec3::ZERO;
        for p in &points[1..] {
            let b = p.as_dvec3() - origin;
            normal += a.cross(b);
            a = b;
        }
        let normal = normal.try_normalize()?;
        // Any unit vector perpendicular to the normal, and the one that completes a
        // right-handed frame: (u, v, normal) makes the outline counter-clockwise.
        let u = normal.any_orthonormal_vector();
        Some(Plane {
            origin,
            u,
            v: normal.cross(u),
        })
    }

    #[inline]
    fn project(&self, p: Vec3) -> [f64; 2] {
        let d = p.as_dvec3() - self.origin;
        [d.dot(self.u), d.dot(self.v)]
    }
}

/// `(b - a) x (c - b)`: positive for a left (convex) turn at `b` of a
/// counter-clockwise outline.
#[inline]
fn turn(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])
}

/// Whether the counter-clockwise `outline` is convex: no turn goes right (beyond
/// what rounding explains), and the turns add up to one full circle (a star drawn in
/// one stroke turns left everywhere, twice round).
fn is_convex(n: usize, outline: impl Fn(usize) -> [f64; 2]) -> bool {
    let mut total = 0.0;
    let (mut a, mut b) = (outline(n - 1), outline(0));
    for i in 0..n {
        let c = outline((i + 1) % n);
        let (e1, e2) = ([b[0] - a[0], b[1] - a[1]], [c[0] - b[0], c[1] - b[1]]);
        let cross = e1[0] * e2[1] - e1[1] * e2[0];
        // Without the rounding allowance of the ear clipper: on a dense curve (a
        // circle of 100,000 corners in `f32`) rounding hides the turns, and a ring
        // drawn that densely would pass for convex. Clipping a convex polygon whose
        // rounding made it look concave costs time, not shape.
        // `cross < -STRAIGHT_TURN * |e1| |e2|`, squared: no square roots per corner.
        let lengths_squared = (e1[0] * e1[0] + e1[1] * e1[1]) * (e2[0] * e2[0] + e2[1] * e2[1]);
        if cross < 0.0 && cross * cross > STRAIGHT_TURN * STRAIGHT_TURN * lengths_squared {
            return false;
        }
        // Four corners that all turn left go round once: a star needs five.
        if n > 4 {
            let dot = e1[0] * e2[0] + e1[1] * e2[1];
            total += cross.atan2(dot);
        }
        (a, b) = (b, c);
    }
    n == 4 || (total - std::f64::consts::TAU).abs() < 1e-3
}

/// Ear clipping on a counter-clockwise outline, corners in a doubly linked ring.
///
/// Event-driven rather than round and round the outline: a corner is tried when it is
/// first met, again when a neighbour is cut (its angle changed), and again when the
/// corner that blocked its ear stops blocking (cut, or turned convex). So each corner
/// is tried a few times, not once per round.
struct EarClipper {
    straight: Straightness,
    points: Vec<[f64; 2]>,
    prev: Vec<u32>,
    next: Vec<u32>,
    removed: Vec<bool>,
    blockers: Blockers,
    /// Corners to try, oldest first, each with the count of its latest entry: an
    /// entry whose count is older is skipped, its corner having been queued again.
    queue: std::collections::VecDeque<(u32, u32)>,
    entry: Vec<u32>,
    entries: u32,
    /// For each corner, the first entry of `waits` for the corners whose ears it
    /// blocks (`NONE`: none). An entry is a waiting corner and the next entry of the
    /// same list; a corner may wait in several lists, and is then merely tried again.
    waiting: Vec<u32>,
    waits: Vec<(u32, u32)>,
}

const NONE: u32 = u32::MAX;

/// A corner's ear and what keeps it from being cut.
enum Ear {
    Cut,
    /// Reflex: wait for a neighbour to be cut.
    Reflex,
    /// Blocked by this corner: wait for it to be cut or turn convex.
    BlockedBy(u32),
}

impl EarClipper {
    fn new(points: Vec<[f64; 2]>, straight: Straightness) -> EarClipper {
        let n = points.len();
        let prev = (0..n as u32)
            .map(|i| (i + n as u32 - 1) % n as u32)
            .collect();
        let next = (0..n as u32).map(|i| (i + 1) % n as u32).collect();
        // Only reflex corners can lie inside a valid ear's triangle without the
        // outline crossing it: convex ones need not be tested. Straight ones are, for
        // rounding may hide that they turn right (the inner side of a dense ring).
        let blockers: Vec<u32> = (0..n)
            .filter(|&i| {
                let [a, b, c] = [(i + n - 1) % n, i, (i + 1) % n].map(|k| points[k]);
                !straight.is_convex(a, b, c)
            })
            .map(|i| i as u32)
            .collect();
        let blockers = Blockers::new(&points, blockers);
        let mut clipper = EarClipper {
            straight,
            removed: vec![false; n],
            points,
            prev,
            next,
            blockers,
            queue: std::collections::VecDeque::with_capacity(3 * n),
            entry: vec![0; n],
            entries: 0,
            waiting: vec![NONE; n],
            waits: Vec::new(),
        };
        for i in 0..n as u32 {
            clipper.enqueue(i);
        }
        clipper
    }

    fn enqueue(&mut self, i: u32) {
        self.entries += 1;
        self.entry[i as usize] = self.entries;
        self.queue.push_back((i, self.entries));
    }

    /// The triangles, and the work done (see [`triangulate_counting_work`]).
    fn run(mut self) -> (Vec<[u32; 3]>, u64) {
        let n = self.points.len();
        let mut triangles = Vec::with_capacity(n - 2);
        let mut remaining = n;
        let mut tries = 0u64;
        // No corner before this one is left (corners are only ever removed).
        let mut first_left = 0;
        while remaining > 3 {
            tries += 1;
            let b = match self.queue.pop_front() {
                Some((b, entry)) if entry == self.entry[b as usize] => b,
                Some(_) => continue,
                None => {
                    // Nothing can be cut properly: the outline crosses itself, and no
                    // cut is right. Cut the first corner left, as it is, so that the
                    // face still gets all its triangles. `cut` queues what that may
                    // free, as for any cut: queueing every corner again here made a
                    // self-crossing outline (random corners, a star wound many times)
                    // quadratic in time and in the queue's memory.
                    while self.removed[first_left] {
                        first_left += 1;
                        tries += 1;
                    }
                    let b = first_left as u32;
                    triangles.push([self.prev[b as usize], b, self.next[b as usize]]);
                    self.cut(b);
                    remaining -= 1;
                    continue;
                }
            };
            if self.removed[b as usize] {
                continue;
            }
            let (a, c) = (self.prev[b as usize], self.next[b as usize]);
            match self.ear(a, b, c) {
                Ear::Cut => {
                    triangles.push([a, b, c]);
                    self.cut(b);
                    remaining -= 1;
                }
                Ear::Reflex => {}
                Ear::BlockedBy(p) => {
                    self.waits.push((b, self.waiting[p as usize]));
                    self.waiting[p as usize] = (self.waits.len() - 1) as u32;
                }
            }
        }
        let b = (0..n as u32)
            .find(|&i| !self.removed[i as usize])
            .unwrap_or(0);
        triangles.push([self.prev[b as usize], b, self.next[b as usize]]);
        (triangles, tries + self.blockers.visits.get())
    }

    fn ear(&self, a: u32, b: u32, c: u32) -> Ear {
        let [pa, pb, pc] = [a, b, c].map(|i| self.points[i as usize]);
        let t = turn(pa, pb, pc);
        // A straight corner (or a zero-width spike) goes at once, as a zero-area
        // triangle that the scene build drops: it changes no area.
        if self.straight.is_straight(t, pa, pb, pc) {
            return Ear::Cut;
        }
        if t < 0.0 {
            return Ear::Reflex;
        }
        let blocker = self.blockers.find_in([pa, pb, pc], |p| {
            if p == a || p == b || p == c {
                return false;
            }
            let q = self.points[p as usize];
            // A corner at the same place as one of the ear's (where the outline
            // touches itself, as at the two sides of a ring's notch) does not block.
            if q == pa || q == pb || q == pc {
                return false;
            }
            turn(pa, pb, q) >= 0.0 && turn(pb, pc, q) >= 0.0 && turn(pc, pa, q) >= 0.0
        });
        match blocker {
            Some(p) => Ear::BlockedBy(p),
            None => Ear::Cut,
        }
    }

    /// Cuts corner `i` off the outline and queues what that may free: its neighbours
    /// (their angles changed) and the corners whose ears it or a neighbour that turned
    /// convex was blocking.
    fn cut(&mut self, i: u32) {
        let (p, n) = (self.prev[i as usize], self.next[i as usize]);
        self.next[p as usize] = n;
        self.prev[n as usize] = p;
        self.removed[i as usize] = true;
        self.stop_blocking(i);
        // Cutting an ear only straightens the corners beside it: one that turns
        // left now never turns right again, so it blocks no ear from here on.
        for j in [p, n] {
            let (before, after) = (self.prev[j as usize], self.next[j as usize]);
            let [a, b, c] = [before, j, after].map(|k| self.points[k as usize]);
            if self.straight.is_convex(a, b, c) {
                self.stop_blocking(j);
            }
        }
        // The corner after the next first: cutting every other corner round the
        // outline (as earcut does) keeps the triangles even, where cutting the
        // neighbour at once would fan out from one corner into slivers.
        self.enqueue(p);
        self.enqueue(n);
    }

    fn stop_blocking(&mut self, i: u32) {
        self.blockers.remove(i);
        let mut entry = std::mem::replace(&mut self.waiting[i as usize], NONE);
        while entry != NONE {
            let (corner, next) = self.waits[entry as usize];
            self.enqueue(corner);
            entry = next;
        }
    }
}

/// Ranges of at most this many corners are leaves, scanned in turn: cheaper than more
/// levels of the tree.
const LEAF: usize = 8;

/// The corners that may block ears, in an implicit k-d tree (the median of each range
/// splits it along its longer side) with the count of corners still in each subtree,
/// so that an ear test visits only the corners near the ear, and none of those gone.
struct Blockers {
    /// Corner indices in tree order.
    items: Vec<u32>,
    /// The axis each node splits its range along (0: x, 1: y).
    axes: Vec<u8>,
    /// The box around the corners of each node's range (min, max), tight rather than
    /// the region its ancestors' split lines bound: a long sliver of an ear that
    /// crosses a dense curve of corners then meets the few nodes near the crossing,
    /// where the loose regions reach far from their corners and meet about sqrt(n).
    boxes: Vec<[[f64; 2]; 2]>,
    points: Vec<[f64; 2]>,
    /// Corners still in the subtree whose root is at each position.
    alive: Vec<u32>,
    /// Position of each corner in `items` (`NONE`: not a blocker).
    position: Vec<u32>,
    /// Nodes visited by searches, for the work count.
    visits: std::cell::Cell<u64>,
}

impl Blockers {
    fn new(points: &[[f64; 2]], mut items: Vec<u32>) -> Blockers {
        /// Splits each range at its median along its longer side: corners along a
        /// line (the teeth of a comb) would make alternating axes look at half the
        /// tree.
        fn build(
            items: &mut [u32],
            axes: &mut [u8],
            boxes: &mut [[[f64; 2]; 2]],
            points: &[[f64; 2]],
        ) {
            if items.len() <= LEAF {
                return;
            }
            let mut min = [f64::INFINITY; 2];
            let mut max = [f64::NEG_INFINITY; 2];
            for &i in items.iter() {
                for a in 0..2 {
                    min[a] = min[a].min(points[i as usize][a]);
                    max[a] = max[a].max(points[i as usize][a]);
                }
            }
            let axis = usize::from(max[1] - min[1] > max[0] - min[0]);
            let mid = items.len() / 2;
            axes[mid] = axis as u8;
            boxes[mid] = [min, max];
            items.select_nth_unstable_by(mid, |&a, &b| {
                points[a as usize][axis].total_cmp(&points[b as usize][axis])
            });
            let (left, right) = items.split_at_mut(mid);
            let (axes_left, axes_right) = axes.split_at_mut(mid);
            let (boxes_left, boxes_right) = boxes.split_at_mut(mid);
            build(left, axes_left, boxes_left, points);
            build(
                &mut right[1..],
                &mut axes_right[1..],
                &mut boxes_right[1..],
                points,
            );
        }
        let mut axes = vec![0; items.len()];
        let mut boxes = vec![[[0.0; 2]; 2]; items.len()];
        build(&mut items, &mut axes, &mut boxes, points);
        let mut position = vec![NONE; points.len()];
        for (at, &i) in items.iter().enumerate() {
            position[i as usize] = at as u32;
        }
        let mut alive = vec![0; items.len()];
        fn count(alive: &mut [u32], lo: usize, hi: usize) {
            if hi - lo <= LEAF {
                return;
            }
            let mid = (lo + hi) / 2;
            alive[mid] = (hi - lo) as u32;
            count(alive, lo, mid);
            count(alive, mid + 1, hi);
        }
        count(&mut alive, 0, items.len());
        Blockers {
            axes,
            boxes,
            points: items.iter().map(|&i| points[i as usize]).collect(),
            items,
            alive,
            position,
            visits: std::cell::Cell::new(0),
        }
    }

    /// Takes corner `i` out, if it is in.
    fn remove(&mut self, i: u32) {
        let at = std::mem::replace(&mut self.position[i as usize], NONE);
        if at == NONE {
            return;
        }
        let at = at as usize;
        let (mut lo, mut hi) = (0, self.items.len());
        while hi - lo > LEAF {
            let mid = (lo + hi) / 2;
            self.alive[mid] -= 1;
            match at.cmp(&mid) {
                std::cmp::Ordering::Equal => break,
                std::cmp::Ordering::Less => hi = mid,
                std::cmp::Ordering::Greater => lo = mid + 1,
            }
        }
    }

    /// The first corner near the counter-clockwise triangle `corners` for which `test`
    /// holds. Subtrees whose region lies wholly outside the triangle are skipped: a
    /// box test alone would look at every corner in the box of a long diagonal sliver
    /// (the spikes of a star).
    fn find_in(&self, corners: [[f64; 2]; 3], test: impl Fn(u32) -> bool) -> Option<u32> {
        let min = [0, 1].map(|a| corners[0][a].min(corners[1][a]).min(corners[2][a]));
        let max = [0, 1].map(|a| corners[0][a].max(corners[1][a]).max(corners[2][a]));
        let triangle = Triangle { corners };
        self.search(0, self.items.len(), min, max, &triangle, &test)
    }

    /// The subtree of `lo..hi`, whose corners lie in the region `min..max` (its
    /// ancestors' split lines, clamped to the triangle's box).
    fn search(
        &self,
        lo: usize,
        hi: usize,
        min: [f64; 2],
        max: [f64; 2],
        triangle: &Triangle,
        test: &impl Fn(u32) -> bool,
    ) -> Option<u32> {
        self.visits.set(self.visits.get() + 1);
        if hi - lo <= LEAF {
            return (lo..hi)
                .find(|&k| {
                    let (i, p) = (self.items[k], self.points[k]);
                    self.position[i as usize] != NONE
                        && (min[0]..=max[0]).contains(&p[0])
                        && (min[1]..=max[1]).contains(&p[1])
                        && test(i)
                })
                .map(|k| self.items[k]);
        }
        let mid = (lo + hi) / 2;
        if self.alive[mid] == 0 || min[0] > max[0] || min[1] > max[1] {
            return None;
        }
        // The node's corners lie in its tight box as well as in the region.
        let [box_min, box_max] = self.boxes[mid];
        let min = [min[0].max(box_min[0]), min[1].max(box_min[1])];
        let max = [max[0].min(box_max[0]), max[1].min(box_max[1])];
        if min[0] > max[0] || min[1] > max[1] || triangle.misses(min, max) {
            return None;
        }
        let p = self.points[mid];
        let i = self.items[mid];
        let axis = usize::from(self.axes[mid]);
        if self.position[i as usize] != NONE
            && (min[0]..=max[0]).contains(&p[0])
            && (min[1]..=max[1]).contains(&p[1])
            && test(i)
        {
            return Some(i);
        }
        let mut left_max = max;
        left_max[axis] = left_max[axis].min(p[axis]);
        if let Some(found) = self.search(lo, mid, min, left_max, triangle, test) {
            return Some(found);
        }
        let mut right_min = min;
        right_min[axis] = right_min[axis].max(p[axis]);
        self.search(mid + 1, hi, right_min, max, triangle, test)
    }
}

/// A counter-clockwise triangle, for pruning the search.
struct Triangle {
    corners: [[f64; 2]; 3],
}

impl Triangle {
    /// Whether the box `min..max` lies wholly on the outer side of an edge: then no
    /// point of it is in the triangle.
    #[inline]
    fn misses(&self, min: [f64; 2], max: [f64; 2]) -> bool {
        (0..3).any(|e| {
            let (p, q) = (self.corners[e], self.corners[(e + 1) % 3]);
            // Inside is to the left of p -> q: the normal (-dy, dx) points in. The box
            // corner farthest along it decides.
            let n = [p[1] - q[1], q[0] - p[0]];
            let x = if n[0] >= 0.0 { max[0] } else { min[0] };
            let y = if n[1] >= 0.0 { max[1] } else { min[1] };
            n[0] * (x - p[0]) + n[1] * (y - p[1]) < 0.0
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn polygon(points: &[(f32, f32)]) -> Vec<Vec3> {
        points.iter().map(|&(x, y)| Vec3::new(x, y, 0.0)).collect()
    }

    /// Twice the signed area of a triangle of the xy plane.
    fn area(points: &[Vec3], [a, b, c]: [u32; 3]) -> f32 {
        let [a, b, c] = [a, b, c].map(|i| points[i as usize]);
        (b - a).cross(c - a).z
    }

    /// The triangles cover exactly the polygon: each has the polygon's orientation
    /// (none folds over), every corner is used, and their areas add up to its area.
    fn check_cover(points: &[Vec3], triangles: &[[u32; 3]]) {
        assert_eq!(triangles.len(), points.len() - 2);
        let n = points.len();
        let polygon_area: f32 = (0..n).map(|i| points[i].cross(points[(i + 1) % n]).z).sum();
        let sum: f32 = triangles.iter().map(|&t| area(points, t)).sum();
        assert!(
            (sum - polygon_area).abs() <= 1e-3 * polygon_area.abs(),
            "{sum} vs {polygon_area}"
        );
        for &t in triangles {
            assert!(area(points, t) * polygon_area.signum() >= -1e-6, "{t:?}");
        }
    }

    #[test]
    fn convex_polygons_keep_the_fan() {
        let square = polygon(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]);
        assert_eq!(triangulate(&square), Triangulation::Fan);
        // Clockwise, and with a straight corner: still convex.
        let clockwise = polygon(&[(0.0, 0.0), (0.0, 1.0), (1.0, 1.0), (1.0, 0.5), (1.0, 0.0)]);
        assert_eq!(triangulate(&clockwise), Triangulation::Fan);
        // All on a line: no plane.
        let line = polygon(&[(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (3.0, 0.0)]);
        assert_eq!(triangulate(&line), Triangulation::Fan);
    }

    #[test]
    fn a_concave_polygon_is_cut_into_ears() {
        // An arrow head whose fan from corner 0 would cover the notch.
        let arrow = polygon(&[(0.0, 0.5), (1.0, 0.0), (0.5, 0.5), (1.0, 1.0)]);
        let Triangulation::Triangles(t) = triangulate(&arrow) else {
            panic!("fan");
        };
        check_cover(&arrow, &t);
        // An L, in a plane that is neither axis-aligned nor flat (slightly bent).
        let l: Vec<Vec3> = [
            (0.0, 0.0),
            (2.0, 0.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ]
        .iter()
        .enumerate()
        .map(|(i, &(x, y))| Vec3::new(x, y, 0.01 * i as f32))
        .collect();
        let Triangulation::Triangles(t) = triangulate(&l) else {
            panic!("fan");
        };
        assert_eq!(t.len(), 4);
        // The notch corner (1, 1) is never inside a triangle: no triangle covers the
        // point (1.5, 1.5).
        let flat: Vec<Vec3> = l.iter().map(|p| Vec3::new(p.x, p.y, 0.0)).collect();
        check_cover(&flat, &t);
    }

    /// A ring drawn as one outline: the outer circle, a cut in, the inner circle the
    /// other way round, and the same cut out.
    pub(crate) fn ring(segments: usize, inner: f32) -> Vec<Vec3> {
        let at = |r: f32, k: usize| {
            let a = std::f32::consts::TAU * k as f32 / segments as f32;
            Vec3::new(r * a.cos(), r * a.sin(), 0.0)
        };
        let mut points: Vec<Vec3> = (0..=segments).map(|k| at(1.0, k % segments)).collect();
        points.extend((0..=segments).map(|k| at(inner, (segments - k) % segments)));
        points
    }

    #[test]
    fn a_ring_keeps_its_hole() {
        for segments in [8, 64, 1000] {
            let points = ring(segments, 0.5);
            let Triangulation::Triangles(t) = triangulate(&points) else {
                panic!("fan");
            };
            check_cover(&points, &t);
            // No triangle covers the centre.
            for &[a, b, c] in &t {
                let [a, b, c] = [a, b, c].map(|i| points[i as usize]);
                let inside = [(a, b), (b, c), (c, a)]
                    .iter()
                    .all(|&(p, q)| (q - p).cross(-p).z > 0.0);
                assert!(!inside, "a triangle covers the hole");
            }
        }
    }

    #[test]
    fn a_self_crossing_outline_still_gives_every_triangle() {
        // A bow tie and a pentagram: no right answer, but n - 2 triangles and no hang.
        let bow = polygon(&[(0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0), (0.5, 2.0)]);
        let star: Vec<(f32, f32)> = (0..5)
            .map(|k| {
                let a = std::f32::consts::TAU * (2 * k) as f32 / 5.0;
                (a.cos(), a.sin())
            })
            .collect();
        for points in [bow, polygon(&star)] {
            match triangulate(&points) {
                Triangulation::Fan => {}
                Triangulation::Triangles(t) => assert_eq!(t.len(), points.len() - 2),
            }
        }
    }

    /// The test shapes with `n` corners: a star, a circle, a comb and a ring.
    fn hard_shapes(n: usize) -> Vec<(&'static str, Vec<Vec3>)> {
        let star: Vec<Vec3> = (0..n)
            .map(|k| {
                let a = std::f32::consts::TAU * k as f32 / n as f32;
                let r = if k % 2 == 0 { 1.0 } else { 0.9 };
                Vec3::new(r * a.cos(), r * a.sin(), 0.0)
            })
            .collect();
        let circle: Vec<Vec3> = (0..n)
            .map(|k| {
                let a = std::f32::consts::TAU * k as f32 / n as f32;
                Vec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let comb: Vec<Vec3> = {
            // Teeth along x, then back along the bottom.
            let teeth = n / 4 - 1;
            let mut p = Vec::new();
            for k in 0..teeth {
                let x = k as f32;
                p.extend([(x, 0.0), (x + 0.5, 10.0), (x + 0.5, 1.0)]);
            }
            p.push((teeth as f32, 0.0));
            p.extend([(teeth as f32, -1.0), (0.0, -1.0)]);
            polygon(&p)
        };
        // Outlines that cross themselves everywhere: corners at random, and a
        // pentagram wound round n / 5 times.
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut random = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        let random: Vec<Vec3> = (0..n).map(|_| Vec3::new(random(), random(), 0.0)).collect();
        let wound: Vec<Vec3> = (0..n)
            .map(|k| {
                let a = std::f32::consts::TAU * 0.4 * k as f32 + 1e-6 * k as f32;
                Vec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        vec![
            ("star", star),
            ("circle", circle),
            ("comb", comb),
            ("ring", ring(n / 2 - 1, 0.9)),
            ("random", random),
            ("wound star", wound),
        ]
    }

    #[test]
    fn two_hundred_thousand_corners_cost_far_less_than_quadratic_work() {
        // The work (corners tried plus tree nodes visited) is counted, not timed: a
        // clock would measure the machine's load. Quadrupling the corners multiplies it
        // by 2.2 (ring), 3.9 (circle), 4.0 (wound star), 4.4 (random corners) and 4.5
        // (comb, stars), as n log n does; quadratic ear clipping would multiply it by
        // 16 and spend some 100,000 steps per corner at 200,000 corners, where these
        // take at most 55. (The stars' long thin ears, searched in the regions of the
        // tree rather than its tight boxes, grew as n^1.5: 11.9 times; queueing every
        // corner again after each forced cut of a self-crossing outline, as n^2.)
        let (small, large) = (50_000, 200_000);
        for ((name, few), (_, many)) in hard_shapes(small).into_iter().zip(hard_shapes(large)) {
            let (_, work_few) = triangulate_counting_work(&few);
            let (result, work_many) = triangulate_counting_work(&many);
            if let Triangulation::Triangles(t) = &result {
                assert_eq!(t.len(), many.len() - 2, "{name}");
            }
            let growth = work_many as f64 / work_few.max(1) as f64;
            assert!(
                growth < 6.0,
                "{name}: work {work_few} -> {work_many} ({growth:.1}x)"
            );
            assert!(
                work_many < 100 * many.len() as u64,
                "{name}: work {work_many}"
            );
        }
    }
}
