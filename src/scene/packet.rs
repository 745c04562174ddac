//! Closest-hit and any-hit queries for packets of up to [`PACKET_SIZE`] coherent rays
//! (camera rays of a 4x4 tile, the shadow rays of such a tile towards one light),
//! through [`WideBvh::walk_packet`](crate::bvh::WideBvh::walk_packet) and the
//! sixteen-ray triangle kernel. The answers are those of [`Scene::intersect`] and
//! [`Scene::occluded`] for each ray, bit for bit:
//!
//! - any-hit: whether some primitive blocks a ray does not depend on the order in
//!   which primitives are tested, and the packet walk visits every box the
//!   single-ray walk visits;
//! - closest hit: each lane computes the single-ray kernel's `t`; what single-ray
//!   traversal returns depends on its visiting order only where two primitives lie at
//!   *exactly* the same distance, or where rounding puts a hit before the entry
//!   distance of a box around it (it may then cull the box). The packet query notices
//!   both (it tests hits at `t <= t_max`, and compares each hit with the greatest box
//!   entry on its way) and re-traces those rays one by one.
//!
//! Scenes with cutout materials take the single-ray queries throughout.

use wide::f32x16;

use super::{Hit, Scene};
use crate::bvh::{PACKET_SIZE, RayPacket, lane_mask, lanes_of};
use crate::math::{Float, Ray};
use crate::shapes::{LANES, PacketRay, PrimHit, Shape, TrianglePacket, triangle_across_rays};

/// Up to how many rays reaching a leaf are tested ray by ray, as single rays test
/// a leaf (its two packets' eight triangles at once), rather than sixteen rays at
/// once per triangle: with few rays, most of the sixteen lanes would be idle.
const FEW_RAYS: u32 = 3;

/// The closest hit of one ray as the packet and lane of its primitive.
pub(super) type LaneHit = Option<(u32, usize, PrimHit)>;

impl Scene {
    /// Asks the cache for the triangle packets `first..first + count` of a leaf.
    #[inline(always)]
    pub(super) fn prefetch_packets(&self, first: u32, count: u32) {
        for packet in &self.packets[first as usize..(first + count) as usize] {
            crate::memory::prefetch_lines(packet, crate::bvh::PREFETCH_LINES);
        }
    }

    /// The closest hit of each of `rays` (at most [`PACKET_SIZE`]) into `hits`, as
    /// [`Scene::intersect`] finds it, bit for bit; fastest when the rays are coherent
    /// (neighbouring camera rays).
    ///
    /// # Panics
    /// If `rays` is empty, longer than [`PACKET_SIZE`], or not as long as `hits`.
    pub fn intersect_packet(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        assert_eq!(rays.len(), hits.len(), "one hit per ray");
        if self.ray_by_ray {
            for (hit, ray) in hits.iter_mut().zip(rays) {
                *hit = self.intersect(ray);
            }
            return;
        }
        if let Some(instances) = &self.instances {
            let found = self.closest_found_packet(instances, rays, (1 << rays.len()) - 1);
            for ((hit, ray), found) in hits.iter_mut().zip(rays).zip(found) {
                *hit = found.map(|found| self.found_hit(instances, ray, found));
            }
            return;
        }
        let found = self.closest_lanes_packet(rays);
        let answers = hits.iter_mut().zip(rays).zip(found);
        // As `Scene::intersect`: texture coordinates and bumps in textured scenes only.
        // One loop for each, so that an untextured hit is built in place: built on
        // the stack in pieces and then copied whole, it stalls the copy's loads.
        if !self.second_phase {
            for ((hit, ray), found) in answers {
                *hit = found
                    .map(|(packet, lane, prim)| self.hit_details_inline(ray, packet, lane, prim));
            }
        } else {
            for ((hit, ray), found) in answers {
                *hit = found
                    .map(|(packet, lane, prim)| self.textured_hit_details(ray, packet, lane, prim));
            }
        }
    }

    /// [`Scene::intersect_primitive`] for each of `rays` (at most [`PACKET_SIZE`]):
    /// the primitive hit first, or `u32::MAX` for a miss, into `ids`.
    ///
    /// # Panics
    /// As [`Scene::intersect_packet`].
    pub fn intersect_primitive_packet(&self, rays: &[Ray], ids: &mut [u32]) {
        assert_eq!(rays.len(), ids.len(), "one id per ray");
        for (id, found) in ids.iter_mut().zip(self.named_packet(rays)) {
            *id = found.map_or(u32::MAX, |(prim, _)| prim);
        }
    }

    /// [`Scene::intersect_primitive`] of each of `rays` (1 to [`PACKET_SIZE`]), as a
    /// packet unless the scene is traced ray by ray.
    #[inline(always)]
    pub(super) fn named_packet(&self, rays: &[Ray]) -> [Option<(u32, PrimHit)>; PACKET_SIZE] {
        if self.ray_by_ray {
            return std::array::from_fn(|k| {
                rays.get(k).and_then(|ray| self.intersect_primitive(ray))
            });
        }
        if let Some(instances) = &self.instances {
            let found = self.closest_found_packet(instances, rays, (1 << rays.len()) - 1);
            return found.map(|found| found.and_then(|found| self.found_prim(instances, found)));
        }
        self.closest_lanes_packet(rays)
            .map(|found| self.named(found))
    }

    /// Which of `rays` (at most [`PACKET_SIZE`]) in the mask `active` something
    /// blocks before its distance in `t_max`, as [`Scene::occluded`] answers, as a
    /// mask. Rays outside `active` are not traced (their `t_max` is not read).
    ///
    /// # Panics
    /// If `rays` is empty, longer than [`PACKET_SIZE`], or not as long as `t_max`.
    pub fn occluded_packet(&self, rays: &[Ray], t_max: &[Float], active: u32) -> u32 {
        assert_eq!(rays.len(), t_max.len(), "one distance per ray");
        let active = active & ((1u32 << rays.len()) - 1);
        if self.ray_by_ray {
            return lanes_of(active)
                .filter(|&r| self.occluded(&rays[r], t_max[r]))
                .fold(0, |mask, r| mask | 1 << r);
        }
        let packet = RayPacket::new(rays);
        let mut limits = [0.0; PACKET_SIZE];
        limits[..rays.len()].copy_from_slice(t_max);
        let mut limits = f32x16::from(limits);
        let blocked = self.blockers_packet(&packet, |ray| rays[ray], active, &mut limits);
        match &self.instances {
            Some(instances) => {
                blocked | instances.blockers_packet(&packet, active & !blocked, &limits)
            }
            None => blocked,
        }
    }

    /// The rays of `packet` in `active` that a primitive of this level blocks before
    /// their `t_max` (not lowered), as a mask; `ray_of(i)` is ray `i` of the packet.
    #[inline(always)]
    pub(super) fn blockers_packet(
        &self,
        packet: &RayPacket,
        ray_of: impl Fn(usize) -> Ray + Copy,
        active: u32,
        limits: &mut f32x16,
    ) -> u32 {
        self.wide.walk_packet_any(
            packet,
            active,
            limits,
            |first, count, reached, t_max| {
                let mut blocked = 0u32;
                for packet_index in first..first + count {
                    let prims = &self.packets[packet_index as usize];
                    let open = reached & !blocked;
                    if prims.holds_spheres() {
                        blocked |= sphere_blockers(prims, ray_of, open, t_max);
                    } else if open.count_ones() <= FEW_RAYS {
                        let limits = t_max.as_array();
                        for ray in lanes_of(open) {
                            if prims.occludes(&PacketRay::new(&ray_of(ray)), limits[ray]) {
                                blocked |= 1 << ray;
                            }
                        }
                    } else {
                        for lane in 0..LANES {
                            let Some(Shape::Triangle(triangle)) = prims.shape(lane) else {
                                break;
                            };
                            let (valid, t, _, _) =
                                triangle_across_rays(&triangle, &packet.origin, &packet.dir);
                            blocked |= (valid & t.simd_lt(*t_max)).to_bitmask() & open;
                        }
                    }
                    if blocked == reached {
                        break;
                    }
                }
                blocked
            },
            |first, count| self.prefetch_packets(first, count),
        )
    }

    /// The closest hit of each ray, packet and lane, as [`Scene::closest_lane`].
    pub(super) fn closest_lanes_packet(&self, rays: &[Ray]) -> [LaneHit; PACKET_SIZE] {
        let mut best: [LaneHit; PACKET_SIZE] = [None; PACKET_SIZE];
        if self.ray_by_ray {
            for (best, ray) in best.iter_mut().zip(rays) {
                *best = self.closest_lane(ray);
            }
            return best;
        }
        let packet = RayPacket::new(rays);
        let mut t_max = f32x16::splat(Float::INFINITY);
        let ties = self.nearest_packet(
            &packet,
            |ray| rays[ray],
            packet.all(),
            &mut t_max,
            None,
            &mut best,
        );
        for ray in lanes_of(ties) {
            best[ray] = self.closest_lane(&rays[ray]);
        }
        best
    }

    /// The closest-hit packet walk of this level for the rays of `packet` in
    /// `active` (`ray_of(i)` is ray `i`): lowers their `t_max` and records each
    /// nearer hit in `best`. Returns the rays whose answer in single-ray traversal
    /// depends on its visiting order: they met two primitives at exactly the same
    /// distance, or a hit before the entry distance of a box around it (this
    /// level's boxes, or the entry `path` into the instance's box that led here).
    #[inline(always)]
    pub(super) fn nearest_packet(
        &self,
        packet: &RayPacket,
        ray_of: impl Fn(usize) -> Ray + Copy,
        active: u32,
        t_max: &mut f32x16,
        path: Option<f32x16>,
        best: &mut [LaneHit; PACKET_SIZE],
    ) -> u32 {
        let mut ties = 0u32;
        let walk = |first: u32,
                    count: u32,
                    reached: u32,
                    t_max: &mut f32x16,
                    path_here: &f32x16| {
            let path = &match path {
                Some(outer) => path_here.fast_max(outer),
                None => *path_here,
            };
            if reached.count_ones() <= FEW_RAYS {
                // The whole leaf ray by ray, as a single ray's walk tests it (its
                // two packets in one eight-lane test), noting what the order of the
                // walk could change.
                let path = path.as_array();
                for ray in lanes_of(reached) {
                    let lanes = PacketRay::new(&ray_of(ray));
                    let limit = &mut t_max.as_mut_array()[ray];
                    let mut nearest = None;
                    let order_matters = self.nearest_in_leaf_noting_order(
                        &lanes,
                        first,
                        count,
                        path[ray],
                        limit,
                        &mut nearest,
                    );
                    ties |= u32::from(order_matters) << ray;
                    if nearest.is_some() {
                        best[ray] = nearest;
                    }
                }
                return;
            }
            for packet_index in first..first + count {
                let prims = &self.packets[packet_index as usize];
                if prims.holds_spheres() {
                    ties |=
                        nearest_spheres(prims, packet_index, ray_of, reached, t_max, path, best);
                    continue;
                }
                for lane in 0..LANES {
                    let Some(Shape::Triangle(triangle)) = prims.shape(lane) else {
                        break;
                    };
                    let (valid, t, u, v) =
                        triangle_across_rays(&triangle, &packet.origin, &packet.dir);
                    let within = (valid & t.simd_le(*t_max)).to_bitmask() & reached;
                    if within == 0 {
                        continue;
                    }
                    let nearer = t.simd_lt(*t_max);
                    let closer = nearer.to_bitmask() & within;
                    ties |= within & !closer;
                    ties |= t.simd_lt(*path).to_bitmask() & closer;
                    // In the register, not lane by lane in memory: the next triangle's
                    // test reads `t_max` whole, and would wait for such stores.
                    *t_max = (nearer & valid & lane_mask(reached)).select(t, *t_max);
                    let (t, u, v) = (t.as_array(), u.as_array(), v.as_array());
                    for ray in lanes_of(closer) {
                        best[ray] = Some((
                            packet_index,
                            lane,
                            PrimHit {
                                t: t[ray],
                                u: u[ray],
                                v: v[ray],
                            },
                        ));
                    }
                }
            }
        };
        self.wide
            .walk_packet_closest(packet, active, t_max, walk, |first, count| {
                self.prefetch_packets(first, count)
            });
        ties
    }
}

/// The sphere packet `prims` (index `packet_index`) for the rays of `reached`, one by
/// one as single-ray traversal tests spheres: lowers `t_max` and records closer hits
/// in `best`; returns the rays whose answer depends on the visiting order (a sphere at
/// exactly their `t_max`, or a hit before `path`, their greatest box entry).
#[inline(never)]
fn nearest_spheres(
    prims: &TrianglePacket,
    packet_index: u32,
    ray_of: impl Fn(usize) -> Ray,
    reached: u32,
    t_max: &mut f32x16,
    path: &f32x16,
    best: &mut [LaneHit; PACKET_SIZE],
) -> u32 {
    let mut ties = 0;
    let path = path.as_array();
    let limits = t_max.as_mut_array();
    for ray in lanes_of(reached) {
        for lane in 0..LANES {
            let Some(shape) = prims.shape(lane) else {
                break;
            };
            // `next_up`: also report a hit at exactly `t_max`, a tie.
            if let Some(hit) = shape.intersect(&ray_of(ray), limits[ray].next_up()) {
                ties |= offer(ray, (packet_index, lane, hit), limits, path, best);
            }
        }
    }
    ties
}

/// Offers ray `ray` a hit at most its limit in `limits`, which becomes its best when
/// nearer; returns the ray's bit when its answer depends on the visiting order (a hit
/// at exactly its limit, or a nearer one before `path`, its greatest box entry).
#[inline(always)]
fn offer(
    ray: usize,
    (packet_index, lane, hit): (u32, usize, PrimHit),
    limits: &mut [Float; PACKET_SIZE],
    path: &[Float; PACKET_SIZE],
    best: &mut [LaneHit; PACKET_SIZE],
) -> u32 {
    if hit.t < limits[ray] {
        limits[ray] = hit.t;
        best[ray] = Some((packet_index, lane, hit));
        u32::from(hit.t < path[ray]) << ray
    } else {
        u32::from(hit.t == limits[ray]) << ray
    }
}

/// The rays of `open` that a sphere of `prims` blocks before their `t_max`.
#[inline(never)]
fn sphere_blockers(
    prims: &TrianglePacket,
    ray_of: impl Fn(usize) -> Ray,
    open: u32,
    t_max: &f32x16,
) -> u32 {
    let limits = t_max.as_array();
    lanes_of(open)
        .filter(|&ray| {
            (0..LANES)
                .map_while(|lane| prims.shape(lane))
                .any(|shape| shape.intersect(&ray_of(ray), limits[ray]).is_some())
        })
        .fold(0, |mask, ray| mask | 1 << ray)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::description::{SceneDescription, SphereDesc, TriangleDesc};
    use crate::material::{Light, Material, MaterialId};
    use crate::math::Vec3;
    use crate::{BvhParams, Camera};
    use rand::{Rng, SeedableRng};

    /// A generated test scene: a bumpy height field of `n x n` quads (a mesh whose
    /// rays often cross shared edges and vertices, where two triangles tie), with
    /// vertex normals; a cloud of random triangles above it; optionally spheres; two
    /// point lights; a mirror and a glass material besides a diffuse one.
    pub(crate) fn generated_scene(n: u32, with_spheres: bool, seed: u64) -> Scene {
        Scene::build(
            generated_description(n, with_spheres, seed),
            &BvhParams::default(),
        )
    }

    /// The description [`generated_scene`] builds.
    pub(crate) fn generated_description(n: u32, with_spheres: bool, seed: u64) -> SceneDescription {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut d = SceneDescription::default();
        let height = |x: f32, z: f32| 0.1 * (3.0 * x).sin() * (2.0 * z).cos();
        for j in 0..=n {
            for i in 0..=n {
                let (x, z) = (
                    2.0 * i as f32 / n as f32 - 1.0,
                    2.0 * j as f32 / n as f32 - 1.0,
                );
                d.positions.push(Vec3::new(x, height(x, z), z));
                d.normals.push(Vec3::new(
                    -0.3 * (3.0 * x).cos(),
                    1.0,
                    0.2 * (2.0 * z).sin(),
                ));
            }
        }
        let at = |i: u32, j: u32| j * (n + 1) + i;
        for j in 0..n {
            for i in 0..n {
                let quad = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                for positions in [[quad[0], quad[2], quad[1]], [quad[0], quad[3], quad[2]]] {
                    d.push_triangle(
                        TriangleDesc {
                            positions,
                            material: MaterialId((i / 3 + j / 5) % 3),
                        },
                        Some(positions),
                    );
                }
            }
        }
        for _ in 0..300 {
            let centre = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(0.1..0.8),
                rng.random_range(-1.0..1.0),
            );
            let first = d.positions.len() as u32;
            for _ in 0..3 {
                let offset = Vec3::new(
                    rng.random_range(-0.08..0.08),
                    rng.random_range(-0.08..0.08),
                    rng.random_range(-0.08..0.08),
                );
                d.positions.push(centre + offset);
            }
            d.triangles.push(TriangleDesc {
                positions: [first, first + 1, first + 2],
                material: MaterialId(0),
            });
        }
        if with_spheres {
            for k in 0..6 {
                d.spheres.push(SphereDesc {
                    center: Vec3::new(-0.75 + 0.3 * k as f32, 0.25, 0.1 * k as f32 - 0.3),
                    radius: 0.12,
                    material: MaterialId((k % 3) as u32),
                });
            }
        }
        let mut diffuse = Material::named("diffuse");
        diffuse.diffuse = Vec3::new(0.7, 0.6, 0.5);
        diffuse.specular = Vec3::splat(0.3);
        diffuse.shininess = 20.0;
        diffuse.ambient = Vec3::splat(0.05);
        let mut mirror = diffuse.clone();
        mirror.albedo = [0.5, 0.5, 0.0];
        let mut glass = diffuse.clone();
        glass.albedo = [0.2, 0.2, 0.6];
        glass.ior = 1.5;
        d.materials = vec![diffuse, mirror, glass];
        d.lights = vec![
            Light::point(Vec3::new(0.5, 2.0, 0.5), Vec3::splat(0.8)),
            Light::point(Vec3::new(-1.5, 1.0, -0.2), Vec3::new(0.3, 0.4, 0.5)),
        ];
        d
    }

    /// Bits of everything a hit holds, so that equality is bitwise.
    fn hit_bits(hit: &Option<Hit>) -> String {
        format!("{hit:?}")
    }

    /// Packet hits and single-ray hits agree exactly on camera rays of 4x4 tiles, and
    /// packet and single-ray shadow rays agree on which are blocked.
    pub(crate) fn check_agreement(scene: &Scene, look_from: Vec3) {
        let camera = Camera::new(look_from, Vec3::new(0.0, 0.1, 0.0), 50.0, 96, 64);
        let (mut checked, mut shadow_checked, mut blocked) = (0, 0, 0);
        for top in (0..64).step_by(4) {
            for left in (0..96).step_by(4) {
                let rays: Vec<Ray> = (0..16)
                    .map(|k| camera.pixel_ray(left + k % 4, top + k / 4))
                    .collect();
                let mut hits = [None; PACKET_SIZE];
                scene.intersect_packet(&rays, &mut hits);
                let mut ids = [0; PACKET_SIZE];
                scene.intersect_primitive_packet(&rays, &mut ids);
                for (k, ray) in rays.iter().enumerate() {
                    let single = scene.intersect(ray);
                    assert_eq!(
                        hit_bits(&hits[k]),
                        hit_bits(&single),
                        "ray {k} at ({left}, {top})"
                    );
                    let id = scene.intersect_primitive(ray).map_or(u32::MAX, |(p, _)| p);
                    assert_eq!(ids[k], id);
                    checked += usize::from(single.is_some());
                }
                for light in &scene.lights {
                    let mut shadow = rays.clone();
                    let mut distances = vec![0.0; 16];
                    let mut active = 0;
                    for (k, hit) in hits.iter().enumerate() {
                        if let Some(hit) = hit {
                            (shadow[k], distances[k]) = hit.spawn_ray_to(light.position);
                            active |= 1 << k;
                        }
                    }
                    let mask = scene.occluded_packet(&shadow, &distances, active);
                    for k in lanes_of(active) {
                        let single = scene.occluded(&shadow[k], distances[k]);
                        assert_eq!(
                            mask >> k & 1 == 1,
                            single,
                            "shadow ray {k} at ({left}, {top})"
                        );
                        shadow_checked += 1;
                        blocked += usize::from(single);
                    }
                    assert_eq!(mask & !active, 0, "inactive rays are never blocked");
                }
            }
        }
        assert!(checked > 1500, "{checked} hits");
        assert!(
            blocked > 100 && blocked < shadow_checked,
            "{blocked} of {shadow_checked} blocked"
        );
    }

    #[test]
    fn packet_queries_agree_exactly_with_single_rays() {
        for (n, spheres, seed) in [(40, false, 1), (97, true, 2)] {
            let scene = generated_scene(n, spheres, seed);
            for look_from in [
                Vec3::new(0.0, 1.5, 2.0),
                Vec3::new(1.7, 0.4, -1.1),
                // Straight down onto the grid: rays through shared vertices and edges.
                Vec3::new(0.0, 3.0, 0.0001),
            ] {
                check_agreement(&scene, look_from);
            }
        }
    }
}
