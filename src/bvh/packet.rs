//! Traversal of the [`WideBvh`] by packets of up to sixteen coherent rays (a 4x4 tile
//! of camera rays, or the shadow rays of such a tile towards one light), the
//! technique of Embree's `rtcIntersect16` and of Wald et al., "Interactive Rendering
//! with Coherent Ray Tracing" (2001): each node is fetched once for the whole packet;
//! its eight child boxes first meet conservative bounds of the whole packet in one
//! eight-lane test ([`Frustum`]), and each child that passes is tested against the
//! sixteen rays in one AVX-512 pass (SIMD across rays); a child none of the packet's
//! rays meets is dropped for all of them at once, and a pending child is dropped
//! without a test when it starts beyond every active ray's current `t_max`. The
//! children kept are prefetched (nodes, and a leaf's items through the caller) while
//! their siblings are handled.
//!
//! Each lane performs exactly the slab test of [`WideBvh::walk_ordered`] for its own
//! ray (same operations on the same values, the near plane chosen by the sign of each
//! ray's direction), so:
//!
//! - an any-hit walk ([`WideBvh::walk_packet_any`]) visits, for each ray, exactly the
//!   leaves single-ray any-hit traversal visits (its `t_max` does not change, so the
//!   order does not matter);
//! - a closest-hit walk ([`WideBvh::walk_packet_closest`]) visits every leaf whose box a
//!   ray enters at or somewhat past its current `t_max` ([`CLOSEST_CULL_MARGIN`]), and
//!   tells the leaf callback each ray's greatest entry distance along the way, so the
//!   caller can see the hits whose fate in single-ray traversal depends on its visiting
//!   order (a hit before the computed entry of a box around it, or two hits at exactly
//!   the same distance) and re-trace those rays one by one.
//!
//! As [`WideBvh`], this knows no geometry: leaves are handed to a closure with the
//! mask of the rays that reached them.

use std::mem::MaybeUninit;

use wide::{f32x8, f32x16, u32x16};

use super::wide::{
    ChildRef, MIN_DIR_COMPONENT, PREFETCH_LINES, RayQuery, SLAB_EXIT_SLACK, STACK_SIZE, WIDTH,
    WideRay,
};
use super::{WideBvh, WideNode};
use crate::math::{Float, Ray};
use crate::memory::prefetch_lines;

/// Rays per packet: one AVX-512 register of `f32` per coordinate.
pub const PACKET_SIZE: usize = 16;

/// Up to [`PACKET_SIZE`] rays in structure-of-arrays form: origins, directions and
/// the reciprocal directions of [`super::RayQuery::new`], lane `i` holding ray `i`. Lanes past
/// the rays given repeat the first ray; callers pass masks that leave them out.
#[derive(Clone, Copy, Debug)]
pub struct RayPacket {
    /// Origin coordinates.
    pub origin: [f32x16; 3],
    /// Unit direction coordinates.
    pub dir: [f32x16; 3],
    /// `1 / dir` per coordinate, exactly as [`super::RayQuery::new`] computes it.
    pub inv_dir: [f32x16; 3],
    /// Number of rays given.
    len: usize,
}

/// Origins and directions of `rays` (1 to [`PACKET_SIZE`]) by coordinate, lanes past
/// the rays given repeating the first ray.
#[inline(always)]
fn transpose_partial(rays: &[Ray]) -> ([f32x16; 3], [f32x16; 3]) {
    let mut origin = [[0.0; PACKET_SIZE]; 3];
    let mut dir = [[0.0; PACKET_SIZE]; 3];
    for lane in 0..PACKET_SIZE {
        let ray = &rays[if lane < rays.len() { lane } else { 0 }];
        for axis in 0..3 {
            origin[axis][lane] = ray.origin[axis];
            dir[axis][lane] = ray.dir[axis];
        }
    }
    (origin.map(f32x16::from), dir.map(f32x16::from))
}

/// [`transpose_partial`] of a full packet: six vector loads and three two-source
/// permutes per coordinate. Written lane by lane, the arrays are read back as vectors
/// before the scalar stores have reached the cache, and each such load waits for
/// them (about a tenth of a primary packet's time on the 11k-triangle dragon).
#[inline(always)]
fn transpose_full(rays: &[Ray; PACKET_SIZE]) -> ([f32x16; 3], [f32x16; 3]) {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    {
        use std::arch::x86_64::{
            __m512, __m512i, _mm512_loadu_ps, _mm512_mask_blend_ps, _mm512_permutex2var_ps,
        };
        /// Floats per ray: `Ray` is `repr(C)`, origin then direction.
        const STRIDE: usize = 6;
        const _: () = assert!(std::mem::size_of::<Ray>() == STRIDE * 4);
        // Coordinate `c` of ray `k` is float `f = 6k + c` of the packet, in vector
        // `f / 16`. A two-source permute picks from 32 floats, by `f % 32`: one for
        // vectors 0-1, one for 2-3, one for 4-5, blended by where `f` lies.
        const fn indices(c: usize) -> [i32; PACKET_SIZE] {
            let mut idx = [0; PACKET_SIZE];
            let mut k = 0;
            while k < PACKET_SIZE {
                idx[k] = ((STRIDE * k + c) % 32) as i32;
                k += 1;
            }
            idx
        }
        const fn from_float(c: usize, first: usize) -> u16 {
            let mut mask = 0;
            let mut k = 0;
            while k < PACKET_SIZE {
                if STRIDE * k + c >= first {
                    mask |= 1 << k;
                }
                k += 1;
            }
            mask
        }
        /// Coordinate `C` of every ray, from the packet's six vectors.
        #[inline(always)]
        fn coordinate<const C: usize>(v: &[__m512; STRIDE]) -> f32x16 {
            // SAFETY: AVX-512F is enabled at compile time; `__m512i`/`[i32; 16]` and
            // `__m512`/`f32x16` are 64 bytes of lanes alike.
            unsafe {
                let idx = std::mem::transmute::<[i32; PACKET_SIZE], __m512i>(const { indices(C) });
                let low = _mm512_permutex2var_ps(v[0], idx, v[1]);
                let middle = _mm512_permutex2var_ps(v[2], idx, v[3]);
                let high = _mm512_permutex2var_ps(v[4], idx, v[5]);
                let r = _mm512_mask_blend_ps(const { from_float(C, 32) }, low, middle);
                let r = _mm512_mask_blend_ps(const { from_float(C, 64) }, r, high);
                std::mem::transmute::<__m512, f32x16>(r)
            }
        }
        let base = rays.as_ptr().cast::<f32>();
        // SAFETY: AVX-512F is enabled at compile time; the loads read the 96 floats
        // of the sixteen `repr(C)` rays (`Ray` holds nothing else, as asserted).
        let v: [__m512; STRIDE] = unsafe {
            [
                _mm512_loadu_ps(base),
                _mm512_loadu_ps(base.add(16)),
                _mm512_loadu_ps(base.add(32)),
                _mm512_loadu_ps(base.add(48)),
                _mm512_loadu_ps(base.add(64)),
                _mm512_loadu_ps(base.add(80)),
            ]
        };
        (
            [
                coordinate::<0>(&v),
                coordinate::<1>(&v),
                coordinate::<2>(&v),
            ],
            [
                coordinate::<3>(&v),
                coordinate::<4>(&v),
                coordinate::<5>(&v),
            ],
        )
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx512f")))]
    transpose_partial(rays)
}

impl RayPacket {
    /// Packs `rays` (1 to [`PACKET_SIZE`] of them).
    ///
    /// # Panics
    /// If `rays` is empty or longer than [`PACKET_SIZE`].
    #[inline]
    pub fn new(rays: &[Ray]) -> RayPacket {
        assert!(
            (1..=PACKET_SIZE).contains(&rays.len()),
            "a packet holds 1 to {PACKET_SIZE} rays"
        );
        let (origin, dir) = match <&[Ray; PACKET_SIZE]>::try_from(rays) {
            Ok(full) => transpose_full(full),
            Err(_) => transpose_partial(rays),
        };
        RayPacket::from_parts(origin, dir, rays.len())
    }

    /// A packet of `len` rays (1 to [`PACKET_SIZE`]) given by coordinates, lane `i`
    /// holding ray `i`: as [`RayPacket::new`] of those rays. Directions need not be
    /// unit (an instance's rays in its mesh's space are not).
    #[inline(always)]
    pub fn from_parts(origin: [f32x16; 3], dir: [f32x16; 3], len: usize) -> RayPacket {
        debug_assert!((1..=PACKET_SIZE).contains(&len));
        // `RayQuery::new`'s reciprocal, lane by lane: tiny components floored in
        // magnitude, then `1 / d`.
        let floor = f32x16::splat(MIN_DIR_COMPONENT);
        let inv_dir = dir.map(|d| {
            let safe = d.abs().simd_lt(floor).bitselect(floor.copysign(d), d);
            f32x16::ONE / safe
        });
        RayPacket {
            origin,
            dir,
            inv_dir,
            len,
        }
    }

    /// Ray `lane` of the packet, bit for bit as given.
    #[inline(always)]
    pub fn ray(&self, lane: usize) -> Ray {
        let at = |v: &[f32x16; 3]| {
            crate::math::Vec3::new(
                v[0].as_array()[lane],
                v[1].as_array()[lane],
                v[2].as_array()[lane],
            )
        };
        Ray {
            origin: at(&self.origin),
            dir: at(&self.dir),
        }
    }

    /// Number of rays given.
    #[inline(always)]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Never true: a packet holds at least one ray.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The mask of the rays given: bit `i` for ray `i`.
    #[inline]
    pub fn all(&self) -> u32 {
        (1u32 << self.len) - 1
    }

    /// All-ones in lane `i` if ray `i` meets the box with planes `planes` with an entry
    /// distance `<= reach[i]` (`< reach[i]` unless `INCLUSIVE`), and each ray's entry
    /// distance. Lane by lane the operations of the single-ray slab test.
    #[inline(always)]
    pub(crate) fn hit_child<const INCLUSIVE: bool>(
        &self,
        planes: &[Float; 6],
        reach: f32x16,
    ) -> (f32x16, f32x16) {
        let mut t_enter = f32x16::ZERO;
        let mut t_exit = f32x16::splat(Float::INFINITY);
        for axis in 0..3 {
            let low = (f32x16::splat(planes[2 * axis]) - self.origin[axis]) * self.inv_dir[axis];
            let high =
                (f32x16::splat(planes[2 * axis + 1]) - self.origin[axis]) * self.inv_dir[axis];
            // For a box in use (min <= max), rounding keeps `low <= high` when the
            // reciprocal is positive and `high <= low` when negative, so min and max
            // pick exactly the planes the single-ray test picks by sign.
            let t_near = low.fast_min(high);
            let t_far = low.fast_max(high);
            t_enter = t_enter.fast_max(t_near);
            t_exit = t_exit.fast_min(t_far);
        }
        let t_exit = t_exit * f32x16::splat(SLAB_EXIT_SLACK);
        let within = if INCLUSIVE {
            t_enter.simd_le(reach)
        } else {
            t_enter.simd_lt(reach)
        };
        (t_enter.simd_le(t_exit) & within, t_enter)
    }
}

/// A pending child of a packet walk: what it is, which rays go there, a distance
/// no greater than any of their entries into its box (the packet frustum's entry,
/// by which a closest-hit walk orders and culls), and where its box is (slot `slot` of node `parent`), so
/// that a closest-hit walk can test a leaf's box again, with the rays' `t_max` of
/// the time it gets there, rather than keep sixteen entry distances per entry.
#[derive(Clone, Copy, Debug)]
struct PacketEntry {
    child: ChildRef,
    rays: u32,
    t_enter: Float,
    parent: u32,
    slot: u32,
}

/// An entry of [`WideBvh::walk_lane`]'s stack: a child, its entry distance and the
/// ray's greatest entry distance on the way there.
type LaneEntry = (ChildRef, Float, Float);

/// The traversal stacks of a packet walk: 80 kB, too big to put on the call stack
/// each time (the probes of a fresh frame cost more than a small packet's walk), so
/// each thread keeps one and lends it to its walks.
struct Stacks {
    packet: Box<[MaybeUninit<PacketEntry>]>,
    lane: Box<[MaybeUninit<LaneEntry>]>,
}

thread_local! {
    /// Two spare sets: a walk of an instance's mesh runs inside a leaf callback of
    /// the top level's walk, and would otherwise allocate its stacks per instance.
    static SPARE_STACKS: [std::cell::Cell<Option<Box<Stacks>>>; 2] =
        const { [std::cell::Cell::new(None), std::cell::Cell::new(None)] };
}

/// The thread's stacks, lent for one walk and given back when dropped (a walk inside
/// a walk inside a leaf callback finds none spare and makes its own).
struct LentStacks(Option<Box<Stacks>>);

impl LentStacks {
    #[inline(always)]
    fn take() -> LentStacks {
        let spare = SPARE_STACKS.with(|cells| cells[0].take().or_else(|| cells[1].take()));
        LentStacks(Some(spare.unwrap_or_else(|| {
            Box::new(Stacks {
                packet: Box::new_uninit_slice(STACK_SIZE),
                lane: Box::new_uninit_slice(STACK_SIZE),
            })
        })))
    }

    #[inline(always)]
    fn stacks(&mut self) -> &mut Stacks {
        self.0.as_mut().expect("lent until dropped")
    }
}

impl Drop for LentStacks {
    #[inline(always)]
    fn drop(&mut self) {
        let stacks = self.0.take();
        SPARE_STACKS.with(|cells| match cells[0].take() {
            None => cells[0].set(stacks),
            // A nested walk gave its set back first.
            first @ Some(_) => {
                cells[0].set(first);
                cells[1].set(stacks);
            }
        });
    }
}

/// The lanes of `mask` as an all-ones/all-zeros vector mask.
#[inline(always)]
pub(crate) fn lane_mask(mask: u32) -> f32x16 {
    const BITS: [u32; PACKET_SIZE] = {
        let mut bits = [0; PACKET_SIZE];
        let mut i = 0;
        while i < PACKET_SIZE {
            bits[i] = 1 << i;
            i += 1;
        }
        bits
    };
    let selected = u32x16::splat(mask) & u32x16::from(BITS);
    f32x16::from_bits(selected.simd_eq(u32x16::ZERO)).bitselect(f32x16::ZERO, ALL_ONES)
}

const ALL_ONES: f32x16 = f32x16::from_bits(u32x16::MAX);

/// The smallest lane of `values`.
#[inline(always)]
pub(crate) fn reduce_min(values: f32x16) -> Float {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    {
        use std::arch::x86_64::{__m512, _mm512_reduce_min_ps};
        // SAFETY: `f32x16` is sixteen `f32` in one 64-byte vector, as `__m512`; the
        // instruction set is enabled at compile time.
        unsafe { _mm512_reduce_min_ps(std::mem::transmute::<f32x16, __m512>(values)) }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx512f")))]
    values
        .to_array()
        .into_iter()
        .fold(Float::INFINITY, Float::min)
}

/// The largest lane of `values`.
#[inline(always)]
fn reduce_max(values: f32x16) -> Float {
    -reduce_min(-values)
}

/// How far past a ray's `t_max` a closest-hit packet walk still enters boxes,
/// relative to `t_max`. A box's computed entry distance can exceed the computed
/// distance of a hit inside it by a rounding error; single-ray traversal, which
/// culls by `entry < t_max` in its own order, then keeps or loses that hit depending
/// on when it got there. Entering a little further makes the packet walk see every hit
/// single-ray traversal can see, unless the kernel's distance falls short of the box
/// by more than this (a hit at a grazing angle of about 1e-4 radians or less).
pub const CLOSEST_CULL_MARGIN: Float = 1.0 + 1.0 / 1024.0;

impl WideBvh {
    /// Visits, for the rays of `packet` in `active`, every leaf each of them may hit
    /// within its `t_max` (entry distance `<= t_max * `[`CLOSEST_CULL_MARGIN`]),
    /// roughly nearest first. `leaf(first_item, item_count, rays, t_max, path_enter)`
    /// is called with the mask of the rays that reached the leaf and, per ray, the
    /// greatest entry distance into the boxes on the way there: a hit nearer than
    /// that lies before a box that single-ray traversal may have culled. It may lower
    /// the rays' `t_max`.
    #[inline(always)]
    pub fn walk_packet_closest<F>(
        &self,
        packet: &RayPacket,
        active: u32,
        t_max: &mut f32x16,
        mut leaf: F,
        prefetch_leaf: impl Fn(u32, u32),
    ) where
        F: FnMut(u32, u32, u32, &mut f32x16, &f32x16),
    {
        self.walk_packet::<true, _, _>(
            packet,
            active,
            t_max,
            |first, count, rays, t_max, path| {
                leaf(first, count, rays, t_max, path);
                0
            },
            prefetch_leaf,
        );
    }

    /// Visits, for the rays of `packet` in `active`, every leaf each of them may hit
    /// within its `t_max`, exactly the leaves single-ray any-hit traversal
    /// ([`WideBvh::walk_any`]) visits for it (entry distance `< t_max`), until each is
    /// finished. `leaf(first_item, item_count, rays, t_max)` is called with the mask of
    /// the rays that reached the leaf and returns those it finished (found blocked),
    /// which the walk then drops. Returns the finished rays.
    #[inline(always)]
    pub fn walk_packet_any<F>(
        &self,
        packet: &RayPacket,
        active: u32,
        t_max: &mut f32x16,
        mut leaf: F,
        prefetch_leaf: impl Fn(u32, u32),
    ) -> u32
    where
        F: FnMut(u32, u32, u32, &f32x16) -> u32,
    {
        self.walk_packet::<false, _, _>(
            packet,
            active,
            t_max,
            |first, count, rays, t_max, _| leaf(first, count, rays, t_max),
            prefetch_leaf,
        )
    }

    #[inline(always)]
    fn walk_packet<const CLOSEST: bool, F, P>(
        &self,
        packet: &RayPacket,
        active: u32,
        t_max: &mut f32x16,
        mut leaf: F,
        prefetch_leaf: P,
    ) -> u32
    where
        F: FnMut(u32, u32, u32, &mut f32x16, &f32x16) -> u32,
        P: Fn(u32, u32),
    {
        let mut finished = 0u32;
        if self.nodes.is_empty() || active == 0 {
            return finished;
        }
        let margin = f32x16::splat(CLOSEST_CULL_MARGIN);
        let mut live = active;
        let mut lent = LentStacks::take();
        let Stacks {
            packet: stack,
            lane: lane_stack,
        } = lent.stacks();
        let mut stack_len = 0usize;
        let mut frustum = Frustum::new(packet, live);
        let mut frustum_rays = live;
        let mut current = PacketEntry {
            child: ChildRef {
                index: 0,
                item_count: 0,
            },
            rays: live,
            t_enter: 0.0,
            parent: 0,
            slot: 0,
        };
        loop {
            let mut rays = current.rays & live;
            // A leaf's box met again, for the rays still in reach (closest hit only:
            // an any-hit walk's reach does not change). Every box on the way there
            // contains it, and rounding is monotonic, so a ray's entry into it is the
            // greatest entry on the ray's way, and a ray that meets it met them all.
            let mut path_enter = f32x16::ZERO;
            if CLOSEST && rays != 0 && current.child.item_count > 0 {
                let parent = &self.nodes[current.parent as usize];
                let planes =
                    [0, 1, 2, 3, 4, 5].map(|p| parent.planes[p].as_array()[current.slot as usize]);
                let (hit, t_enter) = packet.hit_child::<true>(&planes, *t_max * margin);
                rays &= hit.to_bitmask();
                path_enter = t_enter;
            }
            if rays != 0 {
                if current.child.item_count > 0 {
                    let done = leaf(
                        current.child.index,
                        current.child.item_count,
                        rays,
                        t_max,
                        &path_enter,
                    );
                    finished |= done;
                    live &= !done;
                    if live == 0 {
                        return finished;
                    }
                } else if rays.count_ones() <= SINGLE_RAY_BELOW {
                    // Too few rays left for sixteen lanes: walk this subtree ray by ray
                    // (its leaves' own entries are the greatest on the way).
                    for ray in lanes_of(rays) {
                        if live & (1 << ray) == 0 {
                            continue;
                        }
                        let done = self.walk_lane::<CLOSEST, F>(
                            packet,
                            ray,
                            (current.child.index, 0.0),
                            t_max,
                            &mut leaf,
                            lane_stack,
                        );
                        finished |= done;
                        live &= !done;
                    }
                    if live == 0 {
                        return finished;
                    }
                } else {
                    let node = &self.nodes[current.child.index as usize];
                    let planes = node.planes.map(|p| p.to_array());
                    let reach = if CLOSEST { *t_max * margin } else { *t_max };
                    let ray_lanes = lane_mask(rays);
                    // Slots some ray may meet: one test for the whole packet first.
                    if frustum_rays != live {
                        frustum = Frustum::new(packet, live);
                        frustum_rays = live;
                    }
                    let reach_max =
                        reduce_max(ray_lanes.bitselect(reach, f32x16::splat(Float::NEG_INFINITY)));
                    // The frustum's entry into each box, no greater than any of the
                    // packet's rays' (its bounds hold them all), orders and culls the
                    // children: a closest-hit walk may visit a ray's leaves in any
                    // order and culls only boxes beyond every ray's reach, and the
                    // least of sixteen exact entries per child cost camera packets
                    // 3-5% (the 10,000-dragon field and the one dragon).
                    let (mut used, frustum_enter) =
                        frustum.hit_children::<CLOSEST>(node, reach_max);
                    let frustum_enter = frustum_enter.to_array();
                    let run_start = stack_len;
                    while used != 0 {
                        let slot = used.trailing_zeros() as usize;
                        used &= used - 1;
                        let slot_planes = [0, 1, 2, 3, 4, 5].map(|p| planes[p][slot]);
                        let (hit, _) = packet.hit_child::<CLOSEST>(&slot_planes, reach);
                        let hit = hit & ray_lanes;
                        let hits = hit.to_bitmask();
                        // Written whether or not a ray hits, and kept only if one does:
                        // whether a child is hit is too random to branch on.
                        debug_assert!(stack_len < STACK_SIZE);
                        stack[stack_len].write(PacketEntry {
                            child: node.child_ref(slot),
                            rays: hits,
                            t_enter: if CLOSEST { frustum_enter[slot] } else { 0.0 },
                            parent: current.child.index,
                            slot: slot as u32,
                        });
                        if hits != 0 {
                            if node.item_count[slot] > 0 {
                                prefetch_leaf(node.child(slot), node.item_count[slot]);
                            } else {
                                prefetch_lines(
                                    self.nodes.as_ptr().wrapping_add(node.child(slot) as usize),
                                    PREFETCH_LINES,
                                );
                            }
                        }
                        stack_len += usize::from(hits != 0);
                    }
                    if CLOSEST && stack_len > run_start + 1 {
                        // SAFETY: entries `run_start..stack_len` were written just above.
                        let run = unsafe {
                            &mut *(&mut stack[run_start..stack_len] as *mut [_]
                                as *mut [PacketEntry])
                        };
                        // Nearest on top, so that closest hits shrink `t_max` early.
                        for i in 1..run.len() {
                            let entry = run[i];
                            let mut j = i;
                            while j > 0 && run[j - 1].t_enter < entry.t_enter {
                                run[j] = run[j - 1];
                                j -= 1;
                            }
                            run[j] = entry;
                        }
                    }
                }
            }
            // Pop the next pending child that some active ray can still reach.
            loop {
                if stack_len == 0 {
                    return finished;
                }
                stack_len -= 1;
                // SAFETY: every entry below `stack_len` was written before.
                let entry = unsafe { stack[stack_len].assume_init() };
                let rays = entry.rays & live;
                if rays == 0 {
                    continue;
                }
                // Whole-packet rejection: the box starts beyond every ray's reach.
                if CLOSEST
                    && entry.t_enter
                        > reduce_max(
                            lane_mask(rays)
                                .bitselect(*t_max * margin, f32x16::splat(Float::NEG_INFINITY)),
                        )
                {
                    continue;
                }
                current = entry;
                break;
            }
        }
    }

    /// The subtree of node `root` for ray `lane` of `packet` alone, one node's eight
    /// boxes at a time (SIMD across children, as single-ray traversal), with the
    /// culling rule and leaf calls of [`WideBvh::walk_packet`]; `path_enter` is a lower
    /// bound of the ray's entry distances on the way to `root` (0 will do: a leaf's own
    /// entry is the greatest on the way). Returns the ray's bit if the leaf callback
    /// finished it.
    #[inline(always)]
    fn walk_lane<const CLOSEST: bool, F>(
        &self,
        packet: &RayPacket,
        lane: usize,
        (root, path_enter): (u32, Float),
        t_max: &mut f32x16,
        leaf: &mut F,
        stack: &mut [MaybeUninit<LaneEntry>],
    ) -> u32
    where
        F: FnMut(u32, u32, u32, &mut f32x16, &f32x16) -> u32,
    {
        let bit = 1u32 << lane;
        let ray = WideRay::from_parts(
            packet.origin.map(|o| o.as_array()[lane]),
            packet.inv_dir.map(|d| d.as_array()[lane]),
        );
        let mut reach = t_max.as_array()[lane];
        // No prefetching: asking for the leaves and nodes of a packet's lone rays
        // measured no faster (0.998x on the field's camera packets).
        let done = self.walk_one::<CLOSEST, false>(
            &ray,
            (root, path_enter),
            &mut reach,
            |first, count, path, reach| {
                t_max.as_mut_array()[lane] = *reach;
                let done = leaf(first, count, bit, t_max, &f32x16::splat(path)) != 0;
                *reach = t_max.as_array()[lane];
                done
            },
            &|_, _| {},
            stack,
        );
        if done { bit } else { 0 }
    }

    /// The closest-hit walk of one ray with the rules of [`WideBvh::walk_packet_closest`]
    /// rather than [`WideBvh::walk_ordered`]'s: boxes entered up to `t_max *
    /// `[`CLOSEST_CULL_MARGIN`], and `leaf(first_item, item_count, path_enter, t_max)`
    /// told the ray's greatest entry distance on its way (at least `path_enter`, the
    /// entry into whatever box led here), so that the caller can tell, as the packet
    /// walk's leaf tests do, a hit whose fate in the ray's own walk depends on the
    /// order of its leaves. For a ray of a packet that enters an instance's mesh alone,
    /// where sixteen lanes, a packet moved into the mesh's space and its bounds would
    /// be work for one ray. `prefetch_leaf(first_item, item_count)` asks for a leaf's
    /// items as soon as the leaf's parent is tested; nodes put on the stack are asked
    /// for too.
    #[inline(always)]
    pub fn walk_closest_noting_entries<F, P>(
        &self,
        ray: &RayQuery,
        path_enter: Float,
        t_max: &mut Float,
        mut leaf: F,
        prefetch_leaf: P,
    ) where
        F: FnMut(u32, u32, Float, &mut Float),
        P: Fn(u32, u32),
    {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = [const { MaybeUninit::<LaneEntry>::uninit() }; STACK_SIZE];
        self.walk_one::<true, true>(
            &WideRay::new(ray),
            (0, path_enter),
            t_max,
            |first, count, path, t_max| {
                leaf(first, count, path, t_max);
                false
            },
            &prefetch_leaf,
            &mut stack,
        );
    }

    /// The walk of [`WideBvh::walk_lane`] and [`WideBvh::walk_closest_noting_entries`]:
    /// one ray from node `root`, nearest first if `CLOSEST` (entering boxes up to its
    /// `t_max` times [`CLOSEST_CULL_MARGIN`]), any-hit otherwise (up to `t_max`, not
    /// included); `leaf(first_item, item_count, path, t_max)` returns `true` to stop.
    /// With `PREFETCH`, the items of leaves met and the nodes pushed are asked for.
    /// Returns whether the leaf callback stopped the walk.
    #[inline(always)]
    fn walk_one<const CLOSEST: bool, const PREFETCH: bool>(
        &self,
        ray: &WideRay,
        (root, path_enter): (u32, Float),
        t_max: &mut Float,
        mut leaf: impl FnMut(u32, u32, Float, &mut Float) -> bool,
        prefetch_leaf: &impl Fn(u32, u32),
        stack: &mut [MaybeUninit<LaneEntry>],
    ) -> bool {
        let margin = if CLOSEST { CLOSEST_CULL_MARGIN } else { 1.0 };
        let mut stack_len = 0usize;
        let mut current = (
            ChildRef {
                index: root,
                item_count: 0,
            },
            path_enter,
        );
        loop {
            let (child, path) = current;
            if child.item_count > 0 {
                if leaf(child.index, child.item_count, path, t_max) {
                    return true;
                }
            } else {
                let node = &self.nodes[child.index as usize];
                let reach = *t_max * margin;
                let (mut hits, t_enter) = ray.hit_children::<CLOSEST>(node, reach);
                let t_enter = t_enter.as_array();
                let run_start = stack_len;
                while hits != 0 {
                    let slot = hits.trailing_zeros() as usize;
                    hits &= hits - 1;
                    debug_assert!(stack_len < STACK_SIZE);
                    let entry = node.child_ref(slot);
                    if PREFETCH {
                        if entry.item_count > 0 {
                            prefetch_leaf(entry.index, entry.item_count);
                        } else {
                            prefetch_lines(
                                self.nodes.as_ptr().wrapping_add(entry.index as usize),
                                PREFETCH_LINES,
                            );
                        }
                    }
                    stack[stack_len].write((entry, t_enter[slot], path.max(t_enter[slot])));
                    stack_len += 1;
                }
                if CLOSEST && stack_len > run_start + 1 {
                    // SAFETY: entries `run_start..stack_len` were written just above.
                    let run = unsafe {
                        &mut *(&mut stack[run_start..stack_len] as *mut [_] as *mut [LaneEntry])
                    };
                    for i in 1..run.len() {
                        let entry = run[i];
                        let mut j = i;
                        while j > 0 && run[j - 1].1 < entry.1 {
                            run[j] = run[j - 1];
                            j -= 1;
                        }
                        run[j] = entry;
                    }
                }
            }
            loop {
                if stack_len == 0 {
                    return false;
                }
                stack_len -= 1;
                // SAFETY: every entry below `stack_len` was written before.
                let (next, t_enter, path) = unsafe { stack[stack_len].assume_init() };
                if !CLOSEST || t_enter <= *t_max * margin {
                    current = (next, path);
                    break;
                }
            }
        }
    }
}

/// Up to how many rays a packet walk still takes through a node together; fewer go
/// on one by one ([`WideBvh::walk_lane`]), where eight boxes per test beat sixteen
/// mostly idle lanes (as Embree's hybrid packet traversal switches to single rays).
const SINGLE_RAY_BELOW: u32 = 2;

/// The set bits of `mask`, lowest first: the lanes of a ray mask.
#[inline(always)]
pub fn lanes_of(mut mask: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            lane
        })
    })
}

const _: () = assert!(PACKET_SIZE <= 32 && WIDTH <= 32);

/// Conservative bounds of a packet's rays for one test per node (SIMD across the
/// node's eight children, as a single ray): per axis the range of the rays' origins
/// and of their reciprocal directions, from which each child box gets a lower bound
/// of every ray's entry distance and an upper bound of every ray's exit distance.
/// A box the bounds reject is missed by every ray's own slab test (see
/// [`Frustum::hit_children`]), so only the boxes they keep get the sixteen-ray test.
///
/// Embree's coherent packet traversal bounds its packets the same way. Bounds alone
/// (boxes tested ray by ray only at the leaves, as Embree does) measured slower here:
/// the ranges of reciprocal directions are wide for direction components near zero,
/// and over half of the children they kept on the dragon were missed by every ray.
struct Frustum {
    /// Axes whose reciprocal directions share one sign: the others bound nothing.
    axes: [bool; 3],
    /// Index into [`WideNode::planes`] of the plane every ray enters by, per axis.
    near_plane: [usize; 3],
    /// The origin coordinate farthest along the direction (giving the least `plane -
    /// origin` for the near plane, and the least entry with a positive reciprocal).
    near_origin: [f32x8; 3],
    /// The origin coordinate least far along the direction, for the far plane.
    far_origin: [f32x8; 3],
    inv_lo: [f32x8; 3],
    inv_hi: [f32x8; 3],
}

impl Frustum {
    /// Bounds of the rays of `packet` in `rays` (not empty).
    #[inline(always)]
    fn new(packet: &RayPacket, rays: u32) -> Frustum {
        let lanes = lane_mask(rays);
        let low = |v: f32x16| reduce_min(lanes.bitselect(v, f32x16::splat(Float::INFINITY)));
        let high = |v: f32x16| reduce_max(lanes.bitselect(v, f32x16::splat(Float::NEG_INFINITY)));
        let mut frustum = Frustum {
            axes: [false; 3],
            near_plane: [0; 3],
            near_origin: [f32x8::ZERO; 3],
            far_origin: [f32x8::ZERO; 3],
            inv_lo: [f32x8::ZERO; 3],
            inv_hi: [f32x8::ZERO; 3],
        };
        for axis in 0..3 {
            let (inv_lo, inv_hi) = (low(packet.inv_dir[axis]), high(packet.inv_dir[axis]));
            let (origin_lo, origin_hi) = (low(packet.origin[axis]), high(packet.origin[axis]));
            // Reciprocals are never zero (directions are floored in magnitude).
            let positive = inv_lo > 0.0;
            frustum.axes[axis] = positive || inv_hi < 0.0;
            frustum.near_plane[axis] = 2 * axis + usize::from(!positive);
            let (near, far) = if positive {
                (origin_hi, origin_lo)
            } else {
                (origin_lo, origin_hi)
            };
            frustum.near_origin[axis] = f32x8::splat(near);
            frustum.far_origin[axis] = f32x8::splat(far);
            frustum.inv_lo[axis] = f32x8::splat(inv_lo);
            frustum.inv_hi[axis] = f32x8::splat(inv_hi);
        }
        frustum
    }

    /// Bit `i` set unless the bounds show that every ray misses child `i`'s box or
    /// enters it beyond `reach` (at or beyond, unless `INCLUSIVE`), and a lower bound
    /// of the rays' entry distances into each child.
    ///
    /// Why it is conservative, in floating point: each ray's test computes, per axis,
    /// `(plane - origin) * inv_dir` with one rounding per operation, and rounding is
    /// monotonic. With the near plane's `x = plane - origin` at its least for the
    /// origin farthest along the axis, `x * inv_dir` is at least `x_lo * inv_dir`,
    /// and over the reciprocals' range that is least at one of its ends (`x_lo`'s
    /// sign decides which): the minimum of both products bounds every ray's near
    /// distance from below. The far distance is bounded from above the same way, and
    /// the entry (largest near distance, at least 0) and exit (smallest far distance,
    /// widened by the slack) follow.
    #[inline(always)]
    fn hit_children<const INCLUSIVE: bool>(&self, node: &WideNode, reach: Float) -> (u32, f32x8) {
        let mut t_enter = f32x8::ZERO;
        let mut t_exit = f32x8::splat(Float::INFINITY);
        for axis in 0..3 {
            if !self.axes[axis] {
                continue;
            }
            let near = self.near_plane[axis];
            let near_gap = node.planes[near] - self.near_origin[axis];
            let far_gap = node.planes[near ^ 1] - self.far_origin[axis];
            let (inv_lo, inv_hi) = (self.inv_lo[axis], self.inv_hi[axis]);
            t_enter = t_enter.fast_max((near_gap * inv_lo).fast_min(near_gap * inv_hi));
            t_exit = t_exit.fast_min((far_gap * inv_lo).fast_max(far_gap * inv_hi));
        }
        let t_exit = t_exit * f32x8::splat(SLAB_EXIT_SLACK);
        let reach = f32x8::splat(reach);
        let within = if INCLUSIVE {
            t_enter.simd_le(reach)
        } else {
            t_enter.simd_lt(reach)
        };
        // Unused slots have inverted boxes, which an axis left out would not reject.
        let used = node.planes[0].simd_le(node.planes[1]);
        (
            (t_enter.simd_le(t_exit) & within & used).to_bitmask(),
            t_enter,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use rand::{Rng, SeedableRng};

    /// A node whose eight slots hold random boxes near points along `rays`, some
    /// tiny, some off to the side; slot 7 unused.
    fn random_node(rng: &mut impl Rng, rays: &[Ray]) -> WideNode {
        let mut planes = [[0.0; WIDTH]; 6];
        #[allow(clippy::needless_range_loop)] // `slot` indexes the inner arrays
        for slot in 0..WIDTH {
            let ray = &rays[rng.random_range(0..rays.len())];
            let off = Vec3::new(
                rng.random_range(-0.5..0.5),
                rng.random_range(-0.5..0.5),
                rng.random_range(-0.5..0.5),
            );
            let centre = ray.origin + ray.dir * rng.random_range(-0.5..5.0) + off;
            let half = Vec3::new(
                rng.random_range(0.0..0.6),
                rng.random_range(0.0..0.6),
                rng.random_range(0.0..0.6),
            );
            let (min, max) = if slot == 7 {
                (
                    Vec3::splat(Float::INFINITY),
                    Vec3::splat(Float::NEG_INFINITY),
                )
            } else {
                (centre - half, centre + half)
            };
            for axis in 0..3 {
                planes[2 * axis][slot] = min[axis];
                planes[2 * axis + 1][slot] = max[axis];
            }
        }
        WideNode {
            planes: planes.map(f32x8::from),
            link: [0; WIDTH],
            item_count: [0; WIDTH],
        }
    }

    /// Sixteen rays: a camera tile (one origin, close directions), shadow rays (spread
    /// origins, converging on a point), or directions of mixed signs on some axes.
    fn random_rays(rng: &mut impl Rng, kind: usize) -> Vec<Ray> {
        let apex = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(0.0..2.0),
        );
        let aim = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            -1.0,
        );
        let spread = [0.02, 0.3, 2.0][kind];
        (0..PACKET_SIZE)
            .map(|_| {
                let jitter = Vec3::new(
                    rng.random_range(-spread..spread),
                    rng.random_range(-spread..spread),
                    rng.random_range(-spread..spread),
                );
                match kind {
                    0 => Ray::new(apex, (aim + jitter).normalize()),
                    // Origins around `apex`, all aimed at one point.
                    _ => {
                        let origin = apex + jitter;
                        Ray::new(origin, (apex + aim * 4.0 - origin).normalize())
                    }
                }
            })
            .collect()
    }

    /// The frustum never rejects a box that one of the rays' own slab tests accepts,
    /// whatever the reach, and its entry bound is no greater than any such ray's entry.
    #[test]
    fn frustum_rejects_only_boxes_every_ray_misses() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(14);
        let (mut accepted, mut rejected) = (0, 0);
        for round in 0..3000 {
            let rays = random_rays(&mut rng, round % 3);
            let packet = RayPacket::new(&rays);
            let node = random_node(&mut rng, &rays);
            let rays = rng.random_range(1..=u32::from(u16::MAX)) & packet.all();
            let rays = if rays == 0 { 1 } else { rays };
            let reach = [Float::INFINITY, rng.random_range(0.1..8.0)][round % 2];
            let frustum = Frustum::new(&packet, rays);
            let (passed, bound) = frustum.hit_children::<true>(&node, reach);
            let bound = bound.as_array();
            // Slot 7 is unused: the walk never tests such a slot ray by ray.
            for (slot, &bound) in bound.iter().enumerate().take(WIDTH - 1) {
                let planes = [0, 1, 2, 3, 4, 5].map(|p| node.planes[p].as_array()[slot]);
                let (hit, t_enter) = packet.hit_child::<true>(&planes, f32x16::splat(reach));
                let hit = hit.to_bitmask() & rays;
                if hit != 0 {
                    assert!(passed & 1 << slot != 0, "round {round}: slot {slot} culled");
                    for ray in lanes_of(hit) {
                        assert!(bound <= t_enter.as_array()[ray], "round {round}");
                    }
                    accepted += 1;
                } else if passed & 1 << slot == 0 {
                    rejected += 1;
                }
            }
            assert_eq!(passed & 1 << 7, 0, "the unused slot passed");
        }
        // The test means something only if both outcomes occur often.
        assert!(
            accepted > 1000 && rejected > 1000,
            "{accepted} / {rejected}"
        );
    }

    #[test]
    fn full_packets_are_transposed_as_partial_ones() {
        let rays: Vec<Ray> = (0..PACKET_SIZE)
            .map(|k| {
                let k = k as Float;
                Ray {
                    origin: Vec3::new(k, 100.0 + k, 200.0 + k),
                    dir: Vec3::new(300.0 + k, 400.0 + k, 500.0 + k),
                }
            })
            .collect();
        let full: &[Ray; PACKET_SIZE] = rays.as_slice().try_into().unwrap();
        let (origin, dir) = transpose_full(full);
        for (axis, (o, d)) in origin.iter().zip(&dir).enumerate() {
            for (k, ray) in rays.iter().enumerate() {
                assert_eq!(
                    o.as_array()[k],
                    ray.origin[axis],
                    "origin {axis} of ray {k}"
                );
                assert_eq!(
                    d.as_array()[k],
                    ray.dir[axis],
                    "direction {axis} of ray {k}"
                );
            }
        }
        let (partial_origin, partial_dir) = transpose_partial(&rays);
        assert_eq!(
            origin.map(|v| v.to_array()),
            partial_origin.map(|v| v.to_array())
        );
        assert_eq!(dir.map(|v| v.to_array()), partial_dir.map(|v| v.to_array()));
    }
}
