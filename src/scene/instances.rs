//! Two-level scenes: copies of meshes placed by instances
//! ([`SceneDescription::instances`]). Each mesh is built once into a [`Scene`] of its
//! own (its wide BVH, packets and shading data, in object space); a top-level wide
//! BVH over the instances' world boxes leads a ray to the copies it may meet, where
//! it is moved into the mesh's space and traced by the mesh's own single-ray walk.
//! The packet, stream and batch queries walk the top level with a packet
//! ([`Scene::closest_found_packet`], [`Instances::blockers_packet`]) and each copy
//! it reaches with the packet moved into the mesh's space (for closest hits, a copy
//! that only one or two of the packet's rays enter by each of them alone:
//! [`ALONE`]); arrays of incoherent rays walk it as a stream, each copy a ray
//! reaches by that ray alone ([`Scene::intersect_primitives_instanced_streamed`],
//! [`Scene::occluded_instanced_streamed`]). All give the answers of the single-ray
//! queries bit for bit (scenes with cutouts go ray by ray). A scene without
//! instances has no top level and runs the one-level walks it always did.
//!
//! A ray `o + t d` in the world is `o' + t d'` in the mesh's space with
//! `o' = M^-1 o` and `d' = M^-1 d` (not normalized), so distances are the world's
//! and the nearest hit over all instances is found by lowering one `t_max`.
//! Normals go back by the inverse transpose of `M`'s linear part, which keeps a
//! normal facing the ray facing it; a mirroring placement (`det M < 0`) turns the
//! winding, so the hit's front side is the mesh's back.

use glam::{Affine3A, Mat3A};
use wide::f32x16;

use super::*;
use crate::bvh::{PACKET_SIZE, RayPacket, STREAM_RAYS, WIDTH, WideNode, lanes_of};
use crate::description::InstanceDesc;

/// The instances of a two-level scene and the meshes they place.
#[derive(Clone, Debug)]
pub(super) struct Instances {
    /// The top-level BVH, its leaves ranges of `placed`.
    top: WideBvh,
    /// The instances in the top level's leaf order.
    placed: Vec<Placed>,
    /// Their world boxes, in the same order (for [`Scene::validate`]).
    bounds: Vec<Aabb>,
    /// Each mesh built once, in object space.
    pub(super) meshes: Vec<Scene>,
    /// Primitive number of each mesh's first primitive: after the flat level's, the
    /// meshes' in turn ([`Scene::intersect_primitive`] names a copy's primitive by
    /// its mesh's).
    first_prim: Vec<u32>,
    /// Description index of each mesh's first triangle, in the same numbering.
    first_source: Vec<usize>,
    /// Primitives of the flat level and of every mesh once.
    prim_count: usize,
}

/// One instance, ready for rays.
#[derive(Clone, Copy, Debug)]
struct Placed {
    /// Object from world: moves rays into the mesh's space.
    object_from_world: Affine3A,
    /// Inverse transpose of the world-from-object linear part: moves normals out.
    normal_to_world: Mat3A,
    /// The mesh, an index into `Instances::meshes`.
    mesh: u32,
    /// Whether the placement mirrors (negative determinant), which turns the
    /// winding and so which side is the front.
    mirrored: bool,
    /// The instance's index in the description (its object is the flat level's
    /// objects' count plus this).
    instance: u32,
}

impl Placed {
    /// `ray` in the mesh's space (its direction not normalized: distances are kept).
    #[inline(always)]
    fn ray_in_object(&self, ray: &Ray) -> Ray {
        Ray {
            origin: self.object_from_world.transform_point3(ray.origin),
            dir: self.object_from_world.transform_vector3(ray.dir),
        }
    }
}

impl Placed {
    /// The rays of `packet` in the mesh's space, bit for bit as
    /// [`Placed::ray_in_object`] moves each (the same products and sums in the same
    /// order, sixteen rays per operation).
    #[inline(always)]
    fn packet_in_object(&self, packet: &RayPacket) -> RayPacket {
        let m = &self.object_from_world;
        let columns = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis];
        let linear = |v: &[f32x16; 3], row: usize| {
            f32x16::splat(columns[0][row]) * v[0]
                + f32x16::splat(columns[1][row]) * v[1]
                + f32x16::splat(columns[2][row]) * v[2]
        };
        let origin = std::array::from_fn(|row| {
            linear(&packet.origin, row) + f32x16::splat(m.translation[row])
        });
        let dir = std::array::from_fn(|row| linear(&packet.dir, row));
        RayPacket::from_parts(origin, dir, packet.len())
    }
}

/// The closest hit of a ray in a scene with instances: on the flat level (packet,
/// lane, hit) or on a copy (instance in leaf order, then the same in its mesh).
#[derive(Clone, Copy, Debug)]
pub(super) enum Found {
    Flat(u32, usize, PrimHit),
    Copy(u32, u32, usize, PrimHit),
}

/// Up to how many of a packet's rays entering a copy go through it one by one
/// ([`Scene::nearest_alone`]) rather than as the packet moved into the mesh's space.
const ALONE: u32 = 2;

/// The top level's parameters: one instance per leaf (a leaf's instances are each a
/// whole walk of a mesh's BVH, so the SAH prices each on its own).
fn top_params(params: &BvhParams) -> BvhParams {
    BvhParams {
        block_size: 1,
        min_leaf_size: 1,
        max_leaf_size: 1,
        ..*params
    }
}

/// Boxes that together hold every primitive of `mesh` (none for an empty mesh): the
/// boxes of its wide BVH's nodes two levels below the root (a leaf's own where the
/// tree ends sooner), at most 64. An instance's world box is the union of these
/// placed: a box placed with a turn grows by up to the turn's stretch of its
/// diagonal, so many small boxes placed bound a turned mesh far more tightly than
/// its one box does (Embree's instances take the latter), and the top level's
/// rays enter fewer copies for nothing.
fn covering_boxes(mesh: &Scene) -> Vec<Aabb> {
    let nodes = &mesh.wide.nodes;
    let Some(root) = nodes.first() else {
        return Vec::new();
    };
    let used = |node: &WideNode, slot: usize| {
        let b = node.child_bounds(slot);
        (!b.min.cmpgt(b.max).any()).then_some(b)
    };
    let mut boxes = Vec::with_capacity(WIDTH * WIDTH);
    for slot in 0..WIDTH {
        let Some(bounds) = used(root, slot) else {
            continue;
        };
        if root.item_count[slot] > 0 {
            boxes.push(bounds);
            continue;
        }
        let child = &nodes[root.child(slot) as usize];
        boxes.extend((0..WIDTH).filter_map(|s| used(child, s)));
    }
    boxes
}

impl Instances {
    /// Builds every mesh once and the top level over `instances` (instances of a mesh
    /// with no shapes left, or of no mesh, are dropped). Warnings of the meshes'
    /// builds go into `warnings`.
    pub(super) fn build(
        meshes: Vec<SceneDescription>,
        instances: &[InstanceDesc],
        flat: &Scene,
        params: &BvhParams,
        warnings: &mut Vec<String>,
    ) -> Instances {
        let mut first_prim = Vec::with_capacity(meshes.len());
        let mut first_source = Vec::with_capacity(meshes.len());
        let mut prim_count = flat.prim_count();
        let mut source_count = flat
            .source
            .iter()
            .map(|&s| s as usize + 1)
            .max()
            .unwrap_or(0);
        let mut built = Vec::with_capacity(meshes.len());
        for mesh in meshes {
            let triangles = mesh.triangles.len();
            let description = SceneDescription {
                materials: flat.materials.clone(),
                spheres: Vec::new(),
                lights: Vec::new(),
                meshes: Vec::new(),
                instances: Vec::new(),
                warnings: Vec::new(),
                environment: None,
                background: None,
                ..mesh
            };
            let (mut scene, _, _) = Scene::build_level(description, params);
            // Every copy's rays read the mesh at random: on huge pages, a visit
            // waits for the caches but not for page walks as well.
            crate::memory::collapse_into_huge_pages(&scene.wide.nodes);
            crate::memory::collapse_into_huge_pages(&scene.packets);
            // What each mesh skipped is told once for the scene, added up
            // (`Scene::build_instanced`).
            warnings.append(&mut scene.warnings);
            first_prim.push(prim_count as u32);
            first_source.push(source_count);
            prim_count += scene.prim_count();
            source_count += triangles;
            built.push(scene);
        }
        // Each instance's world box: the union of its mesh's covering boxes, placed
        // (never larger than the placed box of the whole mesh, and much smaller
        // when the placement turns it). Once, on all threads: the build asks for
        // each box more than once.
        let covering: Vec<Vec<Aabb>> = built.iter().map(covering_boxes).collect();
        let world: Vec<Option<Aabb>> = instances
            .par_iter()
            .map(|instance| {
                let boxes = covering.get(instance.mesh as usize)?;
                let placed = boxes.iter().map(|&b| instance.world_bounds(b));
                placed.reduce(Aabb::union)
            })
            .collect();
        let world_bounds = |i: usize| world[i];
        let top_params = top_params(params);
        let (bvh, order) = Bvh::build_filtered(instances.len(), world_bounds, &top_params);
        let top = WideBvh::collapse(&bvh, 1, &top_params);
        let bounds = order
            .iter()
            .filter_map(|&i| world_bounds(i as usize))
            .collect();
        let placed = order
            .iter()
            .map(|&i| {
                let instance = &instances[i as usize];
                let m = instance.world_from_object;
                Placed {
                    object_from_world: m.inverse(),
                    normal_to_world: m.matrix3.inverse().transpose(),
                    mesh: instance.mesh,
                    mirrored: m.matrix3.determinant() < 0.0 && !instance.winding_kept,
                    instance: i,
                }
            })
            .collect();
        Instances {
            top,
            placed,
            bounds,
            meshes: built,
            first_prim,
            first_source,
            prim_count,
        }
    }

    /// The nearest hit of `ray` on a copy within `t_max` (lowered to it): instance
    /// (leaf order), packet, lane and hit in the mesh.
    #[inline]
    fn closest(&self, ray: &Ray, t_max: &mut Float) -> Option<(u32, u32, usize, PrimHit)> {
        let query = RayQuery::new(ray);
        let mut found = None;
        self.top
            .walk_ordered(&query, t_max, &self.placed, |first, count, t_max| {
                for index in first..first + count {
                    let placed = &self.placed[index as usize];
                    let local = placed.ray_in_object(ray);
                    let mesh = &self.meshes[placed.mesh as usize];
                    if let Some((packet, lane, hit)) = mesh.closest_lane_within(&local, *t_max) {
                        *t_max = hit.t;
                        found = Some((index, packet, lane, hit));
                    }
                }
                false
            });
        found
    }

    /// The rays of `packet` in `active` that a copy blocks before their `t_max`, as
    /// a mask: the top level walked by the packet, each instance it reaches walked
    /// by the packet moved into its mesh's space. Any-hit answers do not depend on
    /// the order of the walk, so they are [`Instances::occluded`]'s.
    #[inline(always)]
    pub(super) fn blockers_packet(&self, packet: &RayPacket, active: u32, t_max: &f32x16) -> u32 {
        if active == 0 {
            return 0;
        }
        let mut reach = *t_max;
        self.top.walk_packet_any(
            packet,
            active,
            &mut reach,
            |first, count, reached, t_max| {
                let mut blocked = 0;
                for placed in &self.placed[first as usize..(first + count) as usize] {
                    let mesh = &self.meshes[placed.mesh as usize];
                    let local = placed.packet_in_object(packet);
                    let mut reach = *t_max;
                    let open = reached & !blocked;
                    blocked |= mesh.blockers_packet(&local, |ray| local.ray(ray), open, &mut reach);
                    if blocked == reached {
                        break;
                    }
                }
                blocked
            },
            |first, _| crate::memory::prefetch_lines(&self.placed[first as usize], 1),
        )
    }

    /// Whether a copy blocks `ray` (whose `query` the caller made) before `t_max`.
    #[inline]
    fn occluded(&self, ray: &Ray, query: &RayQuery, t_max: Float) -> bool {
        let mut t_max = t_max;
        self.top
            .walk_any(query, &mut t_max, &self.placed, |first, count, t_max| {
                self.placed[first as usize..(first + count) as usize]
                    .iter()
                    .any(|placed| {
                        let mesh = &self.meshes[placed.mesh as usize];
                        mesh.occluded_level(&placed.ray_in_object(ray), *t_max)
                    })
            })
    }

    /// The world hit of instance `index`'s mesh at `hit` (packet, lane), with the
    /// mesh's shading moved out of its space.
    fn hit(&self, ray: &Ray, index: u32, packet: u32, lane: usize, hit: PrimHit) -> Hit {
        let placed = &self.placed[index as usize];
        let mesh = &self.meshes[placed.mesh as usize];
        let local = placed.ray_in_object(ray);
        let inner = if !mesh.second_phase {
            mesh.hit_details(&local, packet, lane, hit)
        } else {
            mesh.textured_hit_details(&local, packet, lane, hit)
        };
        // Both normals face the object-space ray; their inverse-transposed images
        // face the world ray (`(N n) . (M d) = n . d`).
        let to_world = |n: Vec3| try_unit(placed.normal_to_world * n);
        let n = to_world(inner.n).unwrap_or(-ray.dir);
        let perturbed = (mesh.materials.get(inner.material.0 as usize))
            .and_then(|m| m.maps.as_ref())
            .is_some_and(|maps| maps.perturbs_normals());
        let prim = mesh.packets[packet as usize].prim(lane);
        let ns = match prim {
            // Vertex normals placed one by one, then interpolated, as the flattened
            // mesh's are: under a non-uniform scale, placing the interpolated normal
            // would weigh the corners differently.
            Some(prim) if !perturbed => {
                let ns = mesh.shading_normal_with(mesh.shading.get(prim), n, &hit, |v| {
                    to_world(v).unwrap_or(Vec3::ZERO)
                });
                if ns.dot(ray.dir) > 0.0 { -ns } else { ns }
            }
            _ => to_world(inner.ns).unwrap_or(n),
        };
        let placed_hit = Hit {
            t: hit.t,
            p: ray.at(hit.t),
            n,
            ns,
            uv: inner.uv,
            colour: inner.colour,
            // Zero (no coat normal of its own) stays zero.
            coat_ns: to_world(inner.coat_ns).unwrap_or(Vec3::ZERO),
            // A direction in the surface: placed by the linear part itself.
            tangent: if inner.tangent == Vec3::ZERO {
                Vec3::ZERO
            } else {
                try_unit(placed.object_from_world.matrix3.inverse() * inner.tangent)
                    .unwrap_or(Vec3::ZERO)
            },
            // Made in world space from the placed corners and vertex normals, as the
            // flattened mesh's is (the construction does not commute with a
            // non-uniform scale), only where the mesh's own says there is one.
            lift: if inner.lift == Vec3::ZERO {
                Vec3::ZERO
            } else {
                self.placed_lift(placed, mesh, ray, packet, lane, &hit)
            },
            material: inner.material,
            front: inner.front != placed.mirrored,
        };
        match prim {
            Some(prim) if mesh.has_vertex_tangents(prim) => {
                placed_frame(placed, mesh, ray, prim, packet, lane, &hit, placed_hit)
            }
            _ => placed_hit,
        }
    }

    /// [`Hit::lift`] of a copy's hit, in world space: the mesh's triangle and vertex
    /// normals placed, then lifted as a flattened triangle is; zero where the lift
    /// would not face the ray.
    #[cold]
    fn placed_lift(
        &self,
        placed: &Placed,
        mesh: &Scene,
        ray: &Ray,
        packet: u32,
        lane: usize,
        hit: &PrimHit,
    ) -> Vec3 {
        let packet = &mesh.packets[packet as usize];
        let (Some(prim), Some(Shape::Triangle(tri))) = (packet.prim(lane), packet.shape(lane))
        else {
            return Vec3::ZERO;
        };
        let world_from_object = placed.object_from_world.inverse();
        let v0 = world_from_object.transform_point3(tri.v0);
        let placed_tri = Triangle {
            v0,
            e1: world_from_object.transform_point3(tri.v0 + tri.e1) - v0,
            e2: world_from_object.transform_point3(tri.v0 + tri.e2) - v0,
        };
        let lift = mesh.smooth_lift_with(
            mesh.shading.get(prim),
            &placed_tri,
            ray.at(hit.t),
            hit,
            |v| try_unit(placed.normal_to_world * v).unwrap_or(Vec3::ZERO),
        );
        if lift.dot(ray.dir) < 0.0 && lift.is_finite() {
            lift
        } else {
            Vec3::ZERO
        }
    }

    /// Checks the top level and every mesh.
    fn validate(&self) -> Result<(), BvhInvariantError> {
        for mesh in &self.meshes {
            mesh.validate()?;
        }
        self.top
            .validate(self.placed.len(), |i| self.bounds[i as usize])
    }
}

/// A copy's hit (`hit`, as [`Instances::hit`] placed it) on triangle `prim` of
/// `mesh`, which has vertex tangents: its normal and bump maps and its direction of
/// anisotropy made again in world space, in the frame of the placed vertex tangents
/// (by the linear part, as directions in the surface) and normals (by the inverse
/// transpose), as a flattened copy's are.
#[cold]
#[allow(clippy::too_many_arguments)]
fn placed_frame(
    placed: &Placed,
    mesh: &Scene,
    ray: &Ray,
    prim: u32,
    packet: u32,
    lane: usize,
    at: &PrimHit,
    mut hit: Hit,
) -> Hit {
    let Some(Shape::Triangle(tri)) = mesh.packets[packet as usize].shape(lane) else {
        return hit;
    };
    let to_world = |n: Vec3| try_unit(placed.normal_to_world * n);
    // The geometric and shading normals as the mesh's own (not turned to the ray).
    let n = try_unit(tri.normal()).and_then(to_world).unwrap_or(hit.n);
    let ns = mesh.shading_normal_with(mesh.shading.get(prim), n, at, |v| {
        to_world(v).unwrap_or(Vec3::ZERO)
    });
    let linear = placed.object_from_world.matrix3.inverse();
    let mirrored = linear.determinant() < 0.0;
    let frame = || mesh.vertex_frame(prim, ns, at, |t| linear * t, mirrored);
    let turn = |v: Vec3| if ns.dot(ray.dir) > 0.0 { -v } else { v };
    let (bumped, coat) = mesh.perturbed_normals(hit.material, hit.uv, ns, frame);
    if let Some(bumped) = bumped {
        hit.ns = turn(bumped);
        hit.coat_ns = turn(ns);
    }
    if let Some(coat) = coat {
        hit.coat_ns = turn(coat);
    }
    if let Some(tangent) = mesh.anisotropy_tangent(hit.material, hit.uv, frame) {
        hit.tangent = tangent;
    }
    hit
}

impl Scene {
    /// Builds a scene with instances: the description's own shapes as one level,
    /// as [`Scene::build`] builds any scene, then each mesh once and the top level.
    pub(super) fn build_instanced(description: SceneDescription, params: &BvhParams) -> Scene {
        let (mut scene, meshes, instances) = Scene::build_level(description, params);
        let started = std::time::Instant::now();
        let mut warnings = Vec::new();
        let built = Instances::build(meshes, &instances, &scene, params, &mut warnings);
        // One warning per kind of what the levels skipped, with the totals (each mesh
        // counted once, as `raytracer info` counts); a mesh with no shapes left leaves
        // the scene its other shapes.
        scene.skipped = (built.meshes.iter()).fold(scene.skipped, |total, m| total.add(m.skipped));
        let nothing_left = built.placed.is_empty() && scene.prim_count() == 0;
        scene.warn_skipped(nothing_left);
        // Each copy is an object of its own, after the flat level's.
        for (i, instance) in instances.iter().enumerate() {
            (scene.objects).push_after_shapes(format!("instance {i} of mesh {}", instance.mesh));
        }
        scene.warnings.append(&mut warnings);
        scene.build_times.tree += started.elapsed();
        scene.instances = Some(Box::new(built));
        scene.set_lit_by_rig(scene.lit_by_rig);
        // Cutouts are traced ray by ray; other scenes' packets, batches and streams
        // walk the top level with their packets.
        scene.ray_by_ray = scene.has_cutouts
            || (scene.instances.as_ref()).is_some_and(|i| i.meshes.iter().any(|m| m.ray_by_ray));
        scene
    }

    /// [`Scene::intersect`] in a scene with instances: the nearest of the flat
    /// level's hit and the copies' within it.
    #[inline(never)]
    pub(super) fn intersect_instanced(&self, instances: &Instances, ray: &Ray) -> Option<Hit> {
        let found = self.closest_found(instances, ray)?;
        Some(self.found_hit(instances, ray, found))
    }

    /// The closest hit of `ray` in a scene with instances: the flat level's first,
    /// then the copies' nearer than it (strictly: a copy's hit at the flat hit's
    /// distance loses).
    #[inline]
    pub(super) fn closest_found(&self, instances: &Instances, ray: &Ray) -> Option<Found> {
        let flat = self.closest_lane(ray);
        let mut t_max = flat.map_or(Float::INFINITY, |(_, _, hit)| hit.t);
        if let Some((index, packet, lane, hit)) = instances.closest(ray, &mut t_max) {
            return Some(Found::Copy(index, packet, lane, hit));
        }
        let (packet, lane, hit) = flat?;
        Some(Found::Flat(packet, lane, hit))
    }

    /// The [`Hit`] of `ray` at `found`.
    #[inline]
    pub(super) fn found_hit(&self, instances: &Instances, ray: &Ray, found: Found) -> Hit {
        match found {
            Found::Copy(index, packet, lane, hit) => instances.hit(ray, index, packet, lane, hit),
            Found::Flat(packet, lane, hit) if !self.second_phase => {
                self.hit_details(ray, packet, lane, hit)
            }
            Found::Flat(packet, lane, hit) => self.textured_hit_details(ray, packet, lane, hit),
        }
    }

    /// The primitive (numbered as [`Scene::intersect_primitive`] names it) and hit
    /// at `found`.
    #[inline]
    pub(super) fn found_prim(&self, instances: &Instances, found: Found) -> Option<(u32, PrimHit)> {
        match found {
            Found::Copy(index, packet, lane, hit) => {
                let mesh = instances.placed[index as usize].mesh as usize;
                let prim = instances.meshes[mesh].packets[packet as usize].prim(lane)?;
                Some((instances.first_prim[mesh] + prim, hit))
            }
            Found::Flat(packet, lane, hit) => self.named(Some((packet, lane, hit))),
        }
    }

    /// [`Scene::closest_found`] of each of `rays` (1 to [`PACKET_SIZE`]) in the
    /// mask `active` (`None` for the others), bit for bit: the flat level walked by
    /// the packet, then the top level, each instance it reaches walked by the packet
    /// moved into its mesh's space ([`Placed::packet_in_object`]: distances along a
    /// ray are the same in both spaces, so one `t_max` per ray serves all). A ray
    /// whose answer could depend on the order of the walk (as
    /// [`Scene::nearest_packet`] tells, the instance's box entry counted on its way)
    /// is traced again alone: on the flat level before the copies, through the copies
    /// after.
    pub(super) fn closest_found_packet(
        &self,
        instances: &Instances,
        rays: &[Ray],
        active: u32,
    ) -> [Option<Found>; PACKET_SIZE] {
        let packet = RayPacket::new(rays);
        let mut t_max = f32x16::splat(Float::INFINITY);
        let mut flat = [None; PACKET_SIZE];
        let flat_ties = self.nearest_packet(
            &packet,
            |ray| rays[ray],
            active,
            &mut t_max,
            None,
            &mut flat,
        );
        // The flat level's answers first, as a single ray finds them (its floor's
        // flat box makes many ties), so that the copies are searched within them.
        for ray in lanes_of(flat_ties) {
            flat[ray] = self.closest_lane(&rays[ray]);
            t_max.as_mut_array()[ray] = flat[ray].map_or(Float::INFINITY, |(_, _, hit)| hit.t);
        }
        let mut ties = 0;
        let mut copies = [None; PACKET_SIZE];
        // The instance of each ray's nearest copy hit, if any.
        let mut which = [u32::MAX; PACKET_SIZE];
        instances.top.walk_packet_closest(
            &packet,
            active,
            &mut t_max,
            |first, count, reached, t_max, path| {
                for index in first..first + count {
                    let placed = &instances.placed[index as usize];
                    let mesh = &instances.meshes[placed.mesh as usize];
                    if reached.count_ones() <= ALONE {
                        // Each ray through the copy on its own, moved as the packet
                        // would move it, with the packet walk's tie rules.
                        for ray in lanes_of(reached) {
                            let local = placed.ray_in_object(&rays[ray]);
                            let limit = &mut t_max.as_mut_array()[ray];
                            let mut nearest = None;
                            let path = path.as_array()[ray];
                            let order_matters =
                                mesh.nearest_alone(&local, path, limit, &mut nearest);
                            ties |= u32::from(order_matters) << ray;
                            if nearest.is_some() {
                                copies[ray] = nearest;
                                which[ray] = index;
                            }
                        }
                        continue;
                    }
                    let local = placed.packet_in_object(&packet);
                    let before = *t_max;
                    ties |= mesh.nearest_packet(
                        &local,
                        |ray| local.ray(ray),
                        reached,
                        t_max,
                        Some(*path),
                        &mut copies,
                    );
                    // A nearer hit lowers the ray's `t_max`, and only a nearer one.
                    for ray in lanes_of(t_max.simd_lt(before).to_bitmask() & reached) {
                        which[ray] = index;
                    }
                }
            },
            |first, _| crate::memory::prefetch_lines(&instances.placed[first as usize], 1),
        );
        std::array::from_fn(|ray| {
            if active >> ray & 1 == 0 {
                None
            } else if ties >> ray & 1 != 0 {
                // The copies again for this ray alone, within the flat level's hit.
                let mut t_max = flat[ray].map_or(Float::INFINITY, |(_, _, hit)| hit.t);
                match instances.closest(&rays[ray], &mut t_max) {
                    Some((index, packet, lane, hit)) => Some(Found::Copy(index, packet, lane, hit)),
                    None => flat[ray].map(|(packet, lane, hit)| Found::Flat(packet, lane, hit)),
                }
            } else if which[ray] != u32::MAX {
                let (packet, lane, hit) = copies[ray]?;
                Some(Found::Copy(which[ray], packet, lane, hit))
            } else {
                let (packet, lane, hit) = flat[ray]?;
                Some(Found::Flat(packet, lane, hit))
            }
        })
    }

    /// The closest hit of `ray` (in this level's space) nearer than `t_max`, which it
    /// lowers, into `nearest` (left alone if none): the walk of a copy that one ray
    /// of a packet enters alone ([`WideBvh::walk_closest_noting_entries`], the
    /// packet walk's rules for one ray). Returns whether the ray's answer could
    /// depend on the order of the walk (a hit at exactly `t_max`, or one nearer than
    /// a box entry on its way, `path` the entry into the copy's world box): such a
    /// ray is traced again alone.
    #[inline(always)]
    fn nearest_alone(
        &self,
        ray: &Ray,
        path: Float,
        t_max: &mut Float,
        nearest: &mut Option<(u32, usize, PrimHit)>,
    ) -> bool {
        let lanes = PacketRay::new(ray);
        let mut order_matters = false;
        self.wide.walk_closest_noting_entries(
            &RayQuery::new(ray),
            path,
            t_max,
            |first, count, entry, t_max| {
                order_matters |=
                    self.nearest_in_leaf_noting_order(&lanes, first, count, entry, t_max, nearest);
            },
            |first, count| self.prefetch_packets(first, count),
        );
        order_matters
    }

    /// [`Scene::intersect_primitive`] of each of `rays` (at most [`STREAM_RAYS`])
    /// into `hits`, bit for bit: each ray's flat level first, then the top level
    /// walked by the rays together ([`WideBvh::walk_stream_closest`]: each node's
    /// memory and test once for all the rays that reach it, as Embree's stream
    /// calls walk), each copy a ray reaches by that ray alone with the packet walk's
    /// tie rules ([`Scene::nearest_alone`], the copy's box entry counted on its
    /// way). A ray whose answer could depend on the order of the walk is traced
    /// again alone.
    pub(super) fn intersect_primitives_instanced_streamed(
        &self,
        instances: &Instances,
        rays: &[Ray],
        hits: &mut [Option<(u32, PrimHit)>],
    ) {
        debug_assert!(rays.len() <= STREAM_RAYS && rays.len() == hits.len());
        let mut flat = [None; STREAM_RAYS];
        let mut t_max = [Float::INFINITY; STREAM_RAYS];
        let mut queries = [RayQuery::new(&rays[0]); STREAM_RAYS];
        for (i, ray) in rays.iter().enumerate() {
            flat[i] = self.closest_lane(ray);
            t_max[i] = flat[i].map_or(Float::INFINITY, |(_, _, hit)| hit.t);
            queries[i] = RayQuery::new(ray);
        }
        let count = rays.len();
        let mut copies = [None; STREAM_RAYS];
        // The instance of each ray's nearest copy hit, if any.
        let mut which = [u32::MAX; STREAM_RAYS];
        let mut order_matters = 0u64;
        instances.top.walk_stream_closest(
            &queries[..count],
            &mut t_max[..count],
            &instances.placed,
            |ray, first, count, entry, limit| {
                for index in first..first + count {
                    let placed = &instances.placed[index as usize];
                    let mesh = &instances.meshes[placed.mesh as usize];
                    let local = placed.ray_in_object(&rays[ray]);
                    let mut nearest = None;
                    if mesh.nearest_alone(&local, entry, limit, &mut nearest) {
                        order_matters |= 1 << ray;
                    }
                    if nearest.is_some() {
                        copies[ray] = nearest;
                        which[ray] = index;
                    }
                }
            },
        );
        for (ray, hit) in hits.iter_mut().enumerate() {
            *hit = if order_matters >> ray & 1 != 0 {
                self.intersect_primitive_instanced(instances, &rays[ray])
            } else if let Some((packet, lane, found)) = copies[ray] {
                self.found_prim(instances, Found::Copy(which[ray], packet, lane, found))
            } else {
                self.named(flat[ray])
            };
        }
    }

    /// [`Scene::occluded`] of each of `rays` (at most [`STREAM_RAYS`]) within its
    /// reach `t_max[i]`, into `blocked`: each ray's flat level first, then the top
    /// level walked by the rays it leaves open together
    /// ([`WideBvh::walk_stream_any`]), each copy a ray reaches by that ray alone.
    /// Any-hit answers do not depend on the order of the walk.
    pub(super) fn occluded_instanced_streamed(
        &self,
        instances: &Instances,
        rays: &[Ray],
        t_max: &[Float],
        blocked: &mut [bool],
    ) {
        debug_assert!(rays.len() <= STREAM_RAYS && rays.len() == blocked.len());
        let mut reach = [Float::NEG_INFINITY; STREAM_RAYS];
        let mut queries = [RayQuery::new(&rays[0]); STREAM_RAYS];
        for (i, ray) in rays.iter().enumerate() {
            queries[i] = RayQuery::new(ray);
            blocked[i] = self.occluded_level_query(ray, &queries[i], t_max[i]);
            // A ray the flat level blocks enters no box (every entry is at least 0).
            if !blocked[i] {
                reach[i] = t_max[i];
            }
        }
        let count = rays.len();
        let copies = instances.top.walk_stream_any(
            &queries[..count],
            &reach[..count],
            &instances.placed,
            |ray, first, count, t_max| {
                instances.placed[first as usize..(first + count) as usize]
                    .iter()
                    .any(|placed| {
                        let mesh = &instances.meshes[placed.mesh as usize];
                        mesh.occluded_level(&placed.ray_in_object(&rays[ray]), t_max)
                    })
            },
        );
        for (ray, blocked) in blocked.iter_mut().enumerate() {
            *blocked |= copies >> ray & 1 != 0;
        }
    }

    /// [`Scene::intersect_object`] in a scene with instances: a copy's object is its
    /// instance's (see [`Scene::object_names`]).
    #[inline(never)]
    pub(super) fn intersect_object_instanced(
        &self,
        instances: &Instances,
        ray: &Ray,
    ) -> Option<(Hit, u32)> {
        let flat = self.closest_lane(ray);
        let mut t_max = flat.map_or(Float::INFINITY, |(_, _, hit)| hit.t);
        if let Some((index, packet, lane, hit)) = instances.closest(ray, &mut t_max) {
            let placed = &instances.placed[index as usize];
            let object = self.objects.placed_object(placed.instance);
            return Some((instances.hit(ray, index, packet, lane, hit), object));
        }
        self.object_hit(ray, flat?)
    }

    /// [`Scene::intersect_primitive`] in a scene with instances: a copy's primitive is
    /// named by its mesh's (numbered after the flat level's, mesh by mesh).
    #[inline(never)]
    pub(super) fn intersect_primitive_instanced(
        &self,
        instances: &Instances,
        ray: &Ray,
    ) -> Option<(u32, PrimHit)> {
        let found = self.closest_found(instances, ray)?;
        self.found_prim(instances, found)
    }

    /// [`Scene::occluded`] in a scene with instances.
    #[inline(never)]
    pub(super) fn occluded_instanced(
        &self,
        instances: &Instances,
        ray: &Ray,
        t_max: Float,
    ) -> bool {
        let query = RayQuery::new(ray);
        self.occluded_level_query(ray, &query, t_max) || instances.occluded(ray, &query, t_max)
    }

    /// [`Scene::source_index`] of a copy's primitive: its mesh's first triangle's
    /// index in the numbering that follows the flat description's shapes, plus its
    /// index in the mesh.
    pub(super) fn source_index_instanced(&self, instances: &Instances, prim: u32) -> usize {
        let mesh = instances.first_prim.partition_point(|&first| first <= prim) - 1;
        let local = prim - instances.first_prim[mesh];
        instances.first_source[mesh] + instances.meshes[mesh].source_index(local)
    }

    /// Primitives stored: the flat level's and each mesh's once.
    pub(super) fn unique_prim_count(&self) -> usize {
        self.instances
            .as_ref()
            .map_or(self.shading.len(), |i| i.prim_count)
    }

    /// Instances placed (0 in a one-level scene).
    pub fn instance_count(&self) -> usize {
        self.instances.as_ref().map_or(0, |i| i.placed.len())
    }

    /// [`Scene::validate`] of the meshes and top level of a scene with instances.
    pub(super) fn validate_instances(&self) -> Result<(), BvhInvariantError> {
        self.instances.as_ref().map_or(Ok(()), |i| i.validate())
    }
}

#[cfg(test)]
mod tests {
    use super::super::packet_tests::generated_description;
    use super::*;
    use crate::scene::BATCH;
    use glam::{Affine3A, Quat, Vec3A};
    use rand::{Rng, SeedableRng};

    /// A generated mesh placed five times (turned, stretched, mirrored), and the same
    /// copies flattened by the reader's code.
    fn scenes() -> (Scene, Scene) {
        let mesh = generated_description(8, false, 5);
        let mut d = SceneDescription {
            materials: mesh.materials.clone(),
            lights: mesh.lights.clone(),
            ..SceneDescription::default()
        };
        // A floor of the flat level's own, under the copies: its box is flat, so
        // many rays' hits on it come before their box entry (ties the packet walk
        // settles ray by ray).
        for [x, z] in [[-6.0, -6.0], [6.0, -6.0], [6.0, 6.0], [-6.0, 6.0]] {
            d.positions.push(Vec3::new(x, -0.3, z));
        }
        for positions in [[0, 2, 1], [0, 3, 2]] {
            d.triangles.push(TriangleDesc {
                positions,
                material: MaterialId(0),
            });
        }
        d.meshes.push(SceneDescription {
            materials: Vec::new(),
            lights: Vec::new(),
            ..mesh
        });
        let placements = [
            Affine3A::IDENTITY,
            Affine3A::from_translation(Vec3::new(2.5, 0.0, 0.0)),
            Affine3A::from_scale_rotation_translation(
                Vec3::new(1.5, 0.5, 1.0),
                Quat::from_rotation_y(0.7),
                Vec3::new(0.0, 1.0, -2.5),
            ),
            Affine3A::from_scale_rotation_translation(
                Vec3::new(-1.0, 1.0, 1.0),
                Quat::from_rotation_x(0.3),
                Vec3::new(-2.5, 0.2, 0.0),
            ),
            Affine3A::from_scale_rotation_translation(
                Vec3::splat(0.5),
                Quat::from_rotation_z(3.0),
                Vec3::new(0.0, 2.0, 0.0),
            ),
        ];
        for world_from_object in placements {
            d.instances.push(InstanceDesc {
                mesh: 0,
                world_from_object,
                winding_kept: false,
            });
        }
        let mut flat = d.clone();
        flat.flatten_instances().unwrap();
        let params = BvhParams::default();
        (Scene::build(d, &params), Scene::build(flat, &params))
    }

    /// A turned copy's world box is its mesh's covering boxes placed: it holds every
    /// placed vertex and is far smaller than the mesh's one box placed, for a mesh
    /// that leaves its box's corners empty (here a diagonal strip, turned to lie
    /// along x).
    #[test]
    fn a_turned_copy_gets_a_tight_world_box() {
        let mut mesh = SceneDescription::default();
        for i in 0..2000 {
            let t = i as f32 / 1000.0 - 1.0;
            let first = mesh.positions.len() as u32;
            mesh.positions.extend([
                Vec3::new(t, 0.0, t),
                Vec3::new(t + 0.001, 0.0, t),
                Vec3::new(t, 0.001, t),
            ]);
            mesh.triangles.push(TriangleDesc {
                positions: [first, first + 1, first + 2],
                material: MaterialId(0),
            });
        }
        let placement = InstanceDesc {
            mesh: 0,
            world_from_object: Affine3A::from_rotation_y(std::f32::consts::FRAC_PI_4),
            winding_kept: false,
        };
        let whole =
            placement.world_bounds(mesh.positions.iter().fold(Aabb::EMPTY, |b, &p| b.grow(p)));
        let vertices = mesh.positions.clone();
        let mut d = SceneDescription::default();
        d.meshes.push(mesh);
        d.instances.push(placement);
        let scene = Scene::build(d, &BvhParams::default());
        scene.validate().unwrap();
        let world = scene.instances.as_ref().unwrap().bounds[0];
        for &v in &vertices {
            let p = placement.world_from_object.transform_point3(v);
            assert!(
                world.contains(&Aabb { min: p, max: p }),
                "{p:?} outside {world:?}"
            );
        }
        assert!(whole.max.z - whole.min.z > 2.5, "{whole:?}");
        assert!(world.max.z - world.min.z < 0.5, "{world:?}");
    }

    /// A mesh that instances place is asked onto huge pages after its build (its
    /// nodes and packets, which every copy's rays read at random), even where the
    /// build's fresh arrays got small ones.
    #[cfg(target_os = "linux")]
    #[test]
    fn an_instanced_mesh_asks_for_huge_pages() {
        crate::memory::find_huge_pages_dear();
        // 2 x 230^2 triangles: some 26,000 packets, over 4 MiB.
        let mut d = SceneDescription::default();
        d.meshes.push(generated_description(230, false, 7));
        for x in [0.0, 3.0] {
            d.instances.push(InstanceDesc {
                mesh: 0,
                world_from_object: Affine3A::from_translation(Vec3::new(x, 0.0, 0.0)),
                winding_kept: false,
            });
        }
        let scene = Scene::build(d, &BvhParams::default());
        let mesh = &scene.instances.as_ref().unwrap().meshes[0];
        let packets = mesh.packets.as_ptr() as usize;
        let inside = packets.next_multiple_of(2 << 20);
        assert!(inside + (2 << 20) <= packets + std::mem::size_of_val(&mesh.packets[..]));
        if crate::memory::thp_supported() {
            let flags = crate::memory::smaps_field(inside, "VmFlags:");
            assert!(flags.contains(" hg"), "{flags}");
        }
    }

    #[test]
    fn what_the_levels_skip_is_one_warning_per_kind_with_the_totals() {
        // A flat level with 1 degenerate triangle, two meshes with 2 and 3 (each
        // placed twice), and a third mesh with nothing but a degenerate triangle:
        // one warning of 7 (each mesh counted once, as `raytracer info` counts), not
        // one per level ("... (and 3 more like it)"), and no "no shapes left" for the
        // empty mesh while others render.
        let triangle = |positions| TriangleDesc {
            positions,
            material: MaterialId(0),
        };
        let level = |degenerate: u32| SceneDescription {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::X * 2.0],
            triangles: std::iter::once(triangle([0, 1, 2]))
                .chain((0..degenerate).map(|_| triangle([0, 1, 3])))
                .collect(),
            ..SceneDescription::default()
        };
        let mut d = level(1);
        d.materials = vec![crate::material::Material::named("m")];
        d.meshes = vec![level(2), level(3), {
            let mut empty = level(1);
            empty.triangles.remove(0);
            empty
        }];
        for mesh in [0, 0, 1, 1, 2] {
            d.instances.push(InstanceDesc {
                mesh,
                world_from_object: Affine3A::from_translation(Vec3::new(mesh as f32, 0.0, 0.0)),
                winding_kept: false,
            });
        }
        let scene = Scene::build(d, &BvhParams::default());
        assert_eq!(
            scene.warnings,
            ["skipped 7 degenerate (zero-area) triangles"]
        );
        // Nothing at all left: one warning of that.
        let mut d = SceneDescription {
            materials: vec![crate::material::Material::named("m")],
            ..SceneDescription::default()
        };
        d.meshes = vec![{
            let mut empty = level(1);
            empty.triangles.remove(0);
            empty
        }];
        d.instances.push(InstanceDesc {
            mesh: 0,
            world_from_object: Affine3A::IDENTITY,
            winding_kept: false,
        });
        let scene = Scene::build(d, &BvhParams::default());
        assert_eq!(
            scene.warnings,
            [
                "skipped 1 degenerate (zero-area) triangle",
                "the scene has no shapes left to render: every ray misses"
            ]
        );
    }

    #[test]
    fn every_query_family_answers_through_instances_as_the_flattened_scene_does() {
        let (scene, flat) = scenes();
        scene.validate().unwrap();
        assert_eq!(scene.instance_count(), 5);
        assert_eq!(flat.instance_count(), 0);
        let mut rng = rand::rngs::StdRng::seed_from_u64(39);
        let rays: Vec<Ray> = (0..2048)
            .map(|_| {
                let origin = Vec3::new(
                    rng.random_range(-4.0..4.0),
                    rng.random_range(2.0..5.0),
                    rng.random_range(-4.0..4.0),
                );
                let target = Vec3::new(
                    rng.random_range(-4.0..4.0),
                    rng.random_range(-0.5..2.0),
                    rng.random_range(-4.0..4.0),
                );
                Ray::new(origin, target - origin)
            })
            .collect();
        // Against the flattened scene (an independent answer): the same surfaces at
        // the same distances, up to the rounding of the placement.
        let mut hits = 0;
        let mut differ = 0;
        for ray in &rays {
            match (scene.intersect(ray), flat.intersect(ray)) {
                (Some(a), Some(b)) => {
                    hits += 1;
                    let close = (a.t - b.t).abs() <= 1e-4 * b.t.max(1.0)
                        && a.n.dot(b.n) > 0.999
                        && a.ns.dot(b.ns) > 0.999
                        && a.front == b.front
                        && a.material == b.material;
                    differ += usize::from(!close);
                }
                (None, None) => {}
                _ => differ += 1,
            }
            let t = 0.5 * flat.intersect(ray).map_or(10.0, |h| h.t);
            differ += usize::from(scene.occluded(ray, t) != flat.occluded(ray, t));
        }
        assert!(hits > 300, "{hits} hits");
        assert!(differ <= 2, "{differ} of {} rays differ", rays.len());
        // The packet, batch and stream queries give the single-ray answers.
        let mut found = vec![None; rays.len()];
        scene.intersect_primitives(&rays, &mut found);
        let reach: Vec<Float> = rays.iter().map(|_| 3.0).collect();
        let mut blocked = vec![false; rays.len()];
        scene.occluded_rays(&rays, &reach, &mut blocked);
        for (i, ray) in rays.iter().enumerate() {
            assert_eq!(found[i], scene.intersect_primitive(ray));
            assert_eq!(blocked[i], scene.occluded(ray, 3.0));
        }
        for (round, chunk) in rays.chunks_exact(BATCH).enumerate() {
            let batch: &[Ray; BATCH] = chunk.try_into().unwrap();
            // Every ray, then some of them.
            let active = match round % 3 {
                0 => u32::MAX >> (32 - BATCH),
                1 => 0x5a3c,
                _ => 0x0101,
            };
            let mut hits = [None; BATCH];
            scene.intersect_batch(batch, active, &mut hits);
            let mut packet_hits = [None; BATCH];
            scene.intersect_packet(chunk, &mut packet_hits);
            let mut ids = [0; BATCH];
            scene.intersect_primitive_packet(chunk, &mut ids);
            let blocked = scene.occluded_batch(batch, &[3.0; BATCH], active);
            let packet_blocked = scene.occluded_packet(chunk, &[3.0; BATCH], u32::MAX);
            for (k, ray) in chunk.iter().enumerate() {
                let single = scene.intersect(ray);
                let on = active >> k & 1 == 1;
                assert_eq!(hits[k], if on { single } else { None });
                assert_eq!(packet_hits[k], single);
                let id = scene.intersect_primitive(ray).map_or(u32::MAX, |(p, _)| p);
                assert_eq!(ids[k], id);
                assert_eq!(blocked >> k & 1 == 1, on && scene.occluded(ray, 3.0));
                assert_eq!(packet_blocked >> k & 1 == 1, scene.occluded(ray, 3.0));
            }
        }
    }

    /// Packets, batches and streams of an instanced scene without cutouts walk the
    /// top level with their packets rather than ray by ray, and coherent packets
    /// (camera tiles, including rays straight down through the copies' shared edges
    /// and vertices, and their shadow rays) agree with single rays bit for bit.
    #[test]
    fn coherent_packets_through_instances_agree_with_single_rays() {
        let (scene, _) = scenes();
        assert!(!scene.ray_by_ray, "an instanced scene is traced ray by ray");
        for look_from in [
            Vec3::new(0.0, 4.5, 4.0),
            Vec3::new(3.7, 1.4, -2.1),
            Vec3::new(0.0, 6.0, 0.0001),
        ] {
            crate::scene::packet_tests::check_agreement(&scene, look_from);
        }
    }

    /// A flat grid of `n x n` unit cells in the plane `y = 0` (two triangles a
    /// cell), from the origin along +x and +z: rays straight down meet its shared
    /// edges and vertices, where triangles tie.
    fn flat_grid(n: u32) -> SceneDescription {
        let mut mesh = SceneDescription::default();
        for j in 0..=n {
            for i in 0..=n {
                mesh.positions.push(Vec3::new(i as Float, 0.0, j as Float));
            }
        }
        let at = |i: u32, j: u32| j * (n + 1) + i;
        for j in 0..n {
            for i in 0..n {
                let [a, b, c, e] = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                for positions in [[a, c, b], [a, e, c]] {
                    mesh.triangles.push(TriangleDesc {
                        positions,
                        material: MaterialId(0),
                    });
                }
            }
        }
        mesh
    }

    /// Placements of a `size x size` flat grid whose copies overlap it exactly in
    /// its plane, with inverses that are exact: itself, shifted by a quarter cell,
    /// turned a quarter turn about y back over the same square, and mirrored in x
    /// (whose front is the grid's back); each moved by `offset`.
    fn overlapping_placements(size: Float, offset: Vec3) -> [Affine3A; 4] {
        let shift = Affine3A::from_translation(offset);
        [
            Affine3A::IDENTITY,
            Affine3A::from_translation(Vec3::new(0.25, 0.0, 0.5)),
            Affine3A::from_cols(Vec3A::Z, Vec3A::Y, -Vec3A::X, Vec3A::new(0.0, 0.0, size)),
            Affine3A::from_cols(-Vec3A::X, Vec3A::Y, Vec3A::Z, Vec3A::new(size, 0.0, 0.0)),
        ]
        .map(|m| shift * m)
    }

    /// A scene placing `flat_grid(n)` by each of `placements`.
    fn grid_scene(n: u32, placements: impl IntoIterator<Item = Affine3A>) -> Scene {
        let mut d = SceneDescription {
            materials: vec![crate::material::Material::named("grey")],
            ..SceneDescription::default()
        };
        d.meshes.push(flat_grid(n));
        for world_from_object in placements {
            d.instances.push(InstanceDesc {
                mesh: 0,
                world_from_object,
                winding_kept: false,
            });
        }
        let scene = Scene::build(d, &BvhParams::default());
        assert!(!scene.ray_by_ray);
        scene
    }

    /// The packet queries' answers for packets of `rays` (16 at a time) against the
    /// single-ray queries', bit for bit; returns how many rays hit.
    fn check_packets_against_single_rays(scene: &Scene, rays: &[Ray]) -> usize {
        let mut found = vec![None; rays.len()];
        scene.intersect_primitives(rays, &mut found);
        let mut hit_count = 0;
        for (chunk, found) in rays.chunks(16).zip(found.chunks(16)) {
            let mut hits = [None; 16];
            scene.intersect_packet(chunk, &mut hits[..chunk.len()]);
            let mut ids = [0; 16];
            scene.intersect_primitive_packet(chunk, &mut ids[..chunk.len()]);
            for (k, ray) in chunk.iter().enumerate() {
                let single = scene.intersect(ray);
                assert_eq!(format!("{:?}", hits[k]), format!("{single:?}"), "ray {k}");
                let primitive = scene.intersect_primitive(ray);
                assert_eq!(found[k], primitive);
                assert_eq!(ids[k], primitive.map_or(u32::MAX, |(p, _)| p));
                hit_count += usize::from(single.is_some());
            }
        }
        hit_count
    }

    /// Copies of one flat grid in one plane (shifted by quarter cells, turned a
    /// quarter turn, mirrored: placements whose inverses are exact), so that rays
    /// straight down meet several copies at exactly the same distance, on different
    /// triangles and sides: each packet and array query still gives each ray the
    /// copy its single-ray walk finds first.
    #[test]
    fn packets_keep_single_rays_answers_where_copies_tie() {
        let n = 12u32;
        let scene = grid_scene(n, overlapping_placements(n as Float, Vec3::ZERO));
        // Packets of sixteen neighbouring rays straight down through vertices,
        // edges and faces, from several heights.
        let rays: Vec<Ray> = (0..64 * 16)
            .map(|k| {
                let (x, z) = ((k % 47) as Float * 0.25, (k / 16 % 45) as Float * 0.25);
                Ray::new(Vec3::new(x, 1.0 + (k / 16 % 3) as Float, z), -Vec3::Y)
            })
            .collect();
        let hit_count = check_packets_against_single_rays(&scene, &rays);
        assert!(hit_count > rays.len() * 9 / 10, "{hit_count} hits");
    }

    /// Copies that one or two of a packet's rays enter alone (sixteen groups of the
    /// overlapping copies of a small grid, far apart, each group reached by one ray
    /// of a packet, or by two) are walked ray by ray with the packet walk's tie
    /// rules: rays through the grids' shared edges and vertices, where copies and
    /// triangles tie, get their single-ray answers bit for bit.
    #[test]
    fn rays_entering_a_copy_alone_keep_single_rays_answers() {
        let n = 2u32;
        let group = |g: u32| Vec3::new(10.0 * (g % 4) as Float, 0.0, 10.0 * (g / 4) as Float);
        let scene = grid_scene(
            n,
            (0..16).flat_map(|g| overlapping_placements(n as Float, group(g))),
        );
        // Points of a grid cell: a vertex, edge middles, a diagonal point, a face.
        let spots = [
            (1.0, 1.0),
            (0.5, 1.0),
            (1.0, 0.5),
            (0.5, 0.5),
            (0.25, 1.5),
            (1.75, 0.25),
        ];
        let mut rays = Vec::new();
        for (round, &(x, z)) in spots.iter().enumerate() {
            for alone in [true, false] {
                for k in 0..16u32 {
                    // One ray per group, or two (rays k and k + 8 share a group).
                    let g = if alone { k } else { k % 8 };
                    let (dx, dz) = if alone || k < 8 { (x, z) } else { (z, x) };
                    let height = 1.0 + ((round as u32 + k) % 3) as Float;
                    let origin = group(g) + Vec3::new(dx, height, dz);
                    rays.push(Ray::new(origin, -Vec3::Y));
                }
            }
        }
        let hit_count = check_packets_against_single_rays(&scene, &rays);
        assert_eq!(hit_count, rays.len());
    }

    /// Arrays of incoherent rays walk the top level as a stream, each copy a ray
    /// reaches by that ray alone: rays in every direction, and among them rays
    /// straight down through the shared edges and vertices of overlapping copies
    /// (which tie, on different triangles and sides), get their single-ray answers
    /// bit for bit, closest hits and blockers alike.
    #[test]
    fn incoherent_arrays_through_the_top_level_keep_single_rays_answers() {
        let n = 4u32;
        let group = |g: u32| Vec3::new(6.0 * (g % 4) as Float, 0.0, 6.0 * (g / 4) as Float);
        let scene = grid_scene(
            n,
            (0..16).flat_map(|g| overlapping_placements(n as Float, group(g))),
        );
        let instances = scene.instances.as_ref().unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(48);
        let quarter = |rng: &mut rand::rngs::StdRng| rng.random_range(0..=4 * n) as Float * 0.25;
        let rays: Vec<Ray> = (0..STREAM_RAYS * 24)
            .map(|k| {
                let height = rng.random_range(1..4) as Float;
                let origin = group(rng.random_range(0..16))
                    + Vec3::new(quarter(&mut rng), height, quarter(&mut rng));
                if k % 3 == 0 {
                    return Ray::new(origin, -Vec3::Y);
                }
                let target = Vec3::new(
                    rng.random_range(-2.0..26.0),
                    rng.random_range(-1.0..0.5),
                    rng.random_range(-2.0..26.0),
                );
                Ray::new(origin, target - origin)
            })
            .collect();
        let reach: Vec<Float> = rays.iter().map(|_| rng.random_range(0.5..4.0)).collect();
        let (mut hit_count, mut blocked_count) = (0, 0);
        for (rays, reach) in rays.chunks(STREAM_RAYS).zip(reach.chunks(STREAM_RAYS)) {
            let mut found = [None; STREAM_RAYS];
            scene.intersect_primitives_instanced_streamed(instances, rays, &mut found);
            let mut blocked = [false; STREAM_RAYS];
            scene.occluded_instanced_streamed(instances, rays, reach, &mut blocked);
            for (k, ray) in rays.iter().enumerate() {
                let single = scene.intersect_primitive(ray);
                assert_eq!(found[k], single, "ray {k}: {ray:?}");
                assert_eq!(blocked[k], scene.occluded(ray, reach[k]), "ray {k}");
                hit_count += usize::from(single.is_some());
                blocked_count += usize::from(blocked[k]);
            }
        }
        assert!(hit_count > rays.len() / 2, "{hit_count} hits");
        assert!(
            blocked_count > rays.len() / 10 && blocked_count < hit_count,
            "{blocked_count} blocked"
        );
        // The array queries take this walk for such arrays, with the same answers.
        let mut found = vec![None; rays.len()];
        scene.intersect_primitives(&rays, &mut found);
        let mut blocked = vec![false; rays.len()];
        scene.occluded_rays(&rays, &reach, &mut blocked);
        for (k, ray) in rays.iter().enumerate() {
            assert_eq!(found[k], scene.intersect_primitive(ray));
            assert_eq!(blocked[k], scene.occluded(ray, reach[k]));
        }
    }

    /// A packet moved into an instance's space holds, lane by lane, the rays
    /// `Placed::ray_in_object` moves one by one, bit for bit (the mesh walks then
    /// compute what the single-ray walks compute).
    #[test]
    fn packets_move_into_a_mesh_as_single_rays_do() {
        let (scene, _) = scenes();
        let instances = scene.instances.as_ref().unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        for placed in &instances.placed {
            for len in [16, 5] {
                let rays: Vec<Ray> = (0..len)
                    .map(|_| {
                        let v = |rng: &mut rand::rngs::StdRng| {
                            Vec3::new(
                                rng.random_range(-9.0..9.0),
                                rng.random_range(-9.0..9.0),
                                rng.random_range(-9.0..9.0),
                            )
                        };
                        Ray::new(v(&mut rng), v(&mut rng))
                    })
                    .collect();
                let local = placed.packet_in_object(&RayPacket::new(&rays));
                assert_eq!(local.len(), len);
                let expected = RayPacket::new(
                    &rays
                        .iter()
                        .map(|r| placed.ray_in_object(r))
                        .collect::<Vec<_>>(),
                );
                for (k, ray) in rays.iter().enumerate() {
                    let moved = placed.ray_in_object(ray);
                    let got = local.ray(k);
                    assert_eq!(
                        got.origin.to_array().map(f32::to_bits),
                        moved.origin.to_array().map(f32::to_bits)
                    );
                    assert_eq!(
                        got.dir.to_array().map(f32::to_bits),
                        moved.dir.to_array().map(f32::to_bits)
                    );
                    for axis in 0..3 {
                        assert_eq!(
                            local.inv_dir[axis].as_array()[k].to_bits(),
                            expected.inv_dir[axis].as_array()[k].to_bits()
                        );
                    }
                }
            }
        }
    }
}
