//! `Scene::build`: a description into the wide BVH, its packets and shading data in
//! leaf order, with the emitters; and how copies of a primitive are found.

use super::*;
use crate::description::InstanceDesc;

/// What makes a primitive render exactly as another: its kind, material, and the
/// bits of its corners, normals and texture coordinates (or of its centre and radius).
type PrimKey = [u32; 29];

/// The arrays of a description that [`prim_key`] reads.
struct KeyArrays<'a> {
    triangles: &'a [TriangleDesc],
    triangle_normals: &'a [Option<[u32; 3]>],
    triangle_texcoords: &'a [Option<[u32; 3]>],
    spheres: &'a [SphereDesc],
    positions: &'a [Vec3],
    normals: &'a [Vec3],
    texcoords: &'a [Vec2],
}

fn prim_key(i: usize, arrays: &KeyArrays<'_>) -> PrimKey {
    let KeyArrays {
        triangles,
        triangle_normals,
        triangle_texcoords,
        spheres,
        positions,
        normals,
        texcoords,
    } = *arrays;
    fn put(key: &mut PrimKey, at: usize, values: &[Float]) {
        for (k, v) in values.iter().enumerate() {
            key[at + k] = v.to_bits();
        }
    }
    let mut key = [0; 29];
    let Some(t) = triangles.get(i) else {
        let s = &spheres[i - triangles.len()];
        put(&mut key, 2, &[s.center.x, s.center.y, s.center.z, s.radius]);
        key[0] = 1;
        key[1] = s.material.0;
        return key;
    };
    // An index outside its array (a description not made by a reader) stands for
    // itself, as NaN bits no value has.
    let vec3 = |array: &[Vec3], index: u32| {
        array
            .get(index as usize)
            .map_or([Float::from_bits(0x7fc0_0000 | index), 0.0, 0.0], |v| {
                v.to_array()
            })
    };
    for (k, &p) in t.positions.iter().enumerate() {
        put(&mut key, 2 + 3 * k, &vec3(positions, p));
    }
    if let Some(Some(ns)) = triangle_normals.get(i) {
        for (k, &n) in ns.iter().enumerate() {
            put(&mut key, 11 + 3 * k, &vec3(normals, n));
        }
        key[20] = 1;
    }
    if let Some(Some(ts)) = triangle_texcoords.get(i) {
        for (k, &t) in ts.iter().enumerate() {
            let uv = texcoords
                .get(t as usize)
                .map_or([Float::from_bits(0x7fc0_0000 | t), 0.0], |v| v.to_array());
            put(&mut key, 21 + 2 * k, &uv);
        }
        key[27] = 1;
    }
    key[0] = 0;
    key[1] = t.material.0;
    key
}

/// The primitives (original indices) in `ranges` of the leaf order `order` whose key
/// equals that of a primitive of lower index in the same range.
fn duplicates_in(
    ranges: &[std::ops::Range<u32>],
    order: &[u32],
    key: impl Fn(u32) -> PrimKey + Sync,
) -> Vec<u32> {
    ranges
        .par_iter()
        .flat_map_iter(|range| {
            let mut keyed: Vec<(PrimKey, u32)> = order[range.start as usize..range.end as usize]
                .iter()
                .map(|&i| (key(i), i))
                .collect();
            keyed.sort_unstable();
            let copies: Vec<u32> = keyed
                .windows(2)
                .filter(|w| w[0].0 == w[1].0)
                .map(|w| w[1].1)
                .collect();
            copies
        })
        .collect()
}

impl Scene {
    /// Builds the scene: drops degenerate triangles ([`Triangle::is_degenerate`], with
    /// one warning that counts them) and copies of a primitive (which the BVH finds
    /// for free: see [`Bvh::coincident`]), builds the BVH and stores primitives in its
    /// leaf order.
    ///
    /// A description with instances becomes a two-level scene: its own shapes one
    /// level, each of its meshes built once, and a BVH over the instances; without
    /// them (or with every mesh used once, which the readers flatten), one level.
    pub fn build(mut description: SceneDescription, params: &BvhParams) -> Scene {
        if description.has_colours() {
            let mut coloured = vec![false; description.materials.len()];
            for level in std::iter::once(&description).chain(&description.meshes) {
                mark_coloured_materials(level, &mut coloured);
            }
            for (material, _) in (description.materials.iter_mut())
                .zip(coloured)
                .filter(|(_, c)| *c)
            {
                material.maps.get_or_insert_default().vertex_colours = true;
            }
        }
        if description.instances.is_empty() {
            description.meshes = Vec::new();
            let mut scene = Scene::build_level(description, params).0;
            let nothing_left = scene.prim_count() == 0;
            scene.warn_skipped(nothing_left);
            return scene;
        }
        Scene::build_instanced(description, params)
    }

    /// [`Scene::build`] of one level: the description's own shapes (and as emitters,
    /// the copies its instances place), returning its meshes and instances for the
    /// level above.
    pub(super) fn build_level(
        description: SceneDescription,
        params: &BvhParams,
    ) -> (Scene, Vec<SceneDescription>, Vec<InstanceDesc>) {
        let bounds = description.bounds();
        let unlit = description.is_unlit() && description.environment.is_none();
        let SceneDescription {
            positions,
            mut colours,
            normals,
            tangents,
            texcoords,
            triangles,
            triangle_normals,
            triangle_texcoords,
            spheres,
            lights,
            materials,
            environment,
            background,
            lit_by_rig,
            objects,
            warnings,
            meshes,
            instances,
        } = description;
        let started = Mark::now();
        let objects = super::objects::Objects::new(objects, triangles.len(), spheres.len());

        // Step 1: the BVH over the triangles with an area, then the spheres, straight
        // from the description (no second copy of the shapes exists while the
        // builder's own arrays do). Primitive `i < triangles.len()` is triangle `i`,
        // the rest are spheres.
        let corners = |t: &TriangleDesc| t.positions.map(|i| positions[i as usize]);
        let sphere_shape = |s: &SphereDesc| Sphere {
            center: s.center,
            radius: s.radius,
        };
        let triangle_count = triangles.len();
        let bounds_of = |i: usize| match triangles.get(i) {
            Some(t) => {
                let [a, b, c] = corners(t);
                let triangle = Triangle::new(a, b, c);
                // The box is that of the stored form (v0 and edges), whose rounded
                // corners the kernel intersects, not of the file's corners.
                (!triangle.is_degenerate()).then(|| triangle.bounds())
            }
            None => Some(sphere_shape(&spheres[i - triangle_count]).bounds()),
        };
        // The environment's tables (an image's sampling distribution) are made
        // beside the tree: neither reads the other, and the tree's build leaves a
        // core idle at times (its top nodes' serial steps).
        // So are the vertex tangents of the triangles whose material reads a tangent
        // frame (MikkTSpace's, for those the file gives none), from the
        // description's arrays before they are taken apart in leaf order below.
        let tangent_inputs = super::tangents::TangentInputs {
            positions: &positions,
            normals: &normals,
            texcoords: &texcoords,
            tangents: &tangents,
            triangles: &triangles,
            triangle_normals: &triangle_normals,
            triangle_texcoords: &triangle_texcoords,
            materials: &materials,
            object_starts: objects.triangle_starts(),
        };
        let ((environment, vertex_tangents), (mut bvh, mut order)) = rayon::join(
            || {
                rayon::join(
                    || environment.as_ref().map(Environment::new),
                    || tangent_inputs.build(),
                )
            },
            || Bvh::build_filtered(triangle_count + spheres.len(), bounds_of, params),
        );
        drop(tangents);
        // Copies of one primitive pile up in the BVH's coincident ranges, where every
        // ray would test each copy (200,000 copies of a triangle took minutes to
        // render): drop all but the first of each, and build again without them.
        let mut duplicates = 0;
        if !bvh.coincident.is_empty() {
            let arrays = KeyArrays {
                triangles: &triangles,
                triangle_normals: &triangle_normals,
                triangle_texcoords: &triangle_texcoords,
                spheres: &spheres,
                positions: &positions,
                normals: &normals,
                texcoords: &texcoords,
            };
            let key = |i: u32| prim_key(i as usize, &arrays);
            let copies = duplicates_in(&bvh.coincident, &order, key);
            if !copies.is_empty() {
                duplicates = copies.len();
                let mut dropped = vec![false; triangle_count + spheres.len()];
                for i in copies {
                    dropped[i as usize] = true;
                }
                (bvh, order) = Bvh::build_filtered(
                    triangle_count + spheres.len(),
                    |i| if dropped[i] { None } else { bounds_of(i) },
                    params,
                );
            }
        }

        let tree_built = Mark::now();
        // Told by the whole scene's build (`Scene::warn_skipped`): a scene of several
        // levels warns once with the totals.
        let skipped = Skipped {
            degenerate: triangle_count + spheres.len() - order.len() - duplicates,
            duplicates,
        };
        let area_lights = collect_area_lights(
            (&positions, &texcoords),
            &triangles,
            &triangle_texcoords,
            &spheres,
            &materials,
            (&meshes, &instances),
        );
        // An unlit scene is warned of (and lit) by `SceneDescription::add_default_light`,
        // which knows the mode.

        // Step 2: the wide BVH, its packets and the shading data in leaf order, in one
        // pass over the description (each primitive's description is read once, at a
        // random place); then the binary BVH can go.
        let prim_of = |prim: u32| {
            let i = order[prim as usize] as usize;
            match triangles.get(i) {
                Some(t) => {
                    let [a, b, c] = corners(t);
                    let shading = PrimShading {
                        material: t.material,
                        normals: (triangle_normals.get(i).copied().flatten())
                            .unwrap_or([NO_NORMALS; 3]),
                    };
                    (Shape::Triangle(Triangle::new(a, b, c)), shading)
                }
                None => {
                    let s = &spheres[i - triangle_count];
                    let shading = PrimShading {
                        material: s.material,
                        normals: [NO_NORMALS; 3],
                    };
                    (Shape::Sphere(sphere_shape(s)), shading)
                }
            }
        };
        // Per-primitive normals only where some triangle has them.
        let with_normals = !normals.is_empty() && triangle_normals.par_iter().any(|n| n.is_some());
        // Triangle meshes (most big scenes) count their packets without a look.
        let has_spheres = !spheres.is_empty();
        let is_sphere = |prim: u32| has_spheres && order[prim as usize] as usize >= triangle_count;
        // What `prim_of` reads, asked for ahead: the description (at a random place
        // in a big array), then the corners it names.
        let fetch = |prim: u32, corners: bool| {
            let i = order[prim as usize] as usize;
            if let Some(t) = triangles.get(i) {
                if corners {
                    for &p in &t.positions {
                        if let Some(p) = positions.get(p as usize) {
                            memory::prefetch_lines(p, 1);
                        }
                    }
                } else {
                    memory::prefetch_lines(t, 1);
                    if let Some(n) = triangle_normals.get(i) {
                        memory::prefetch_lines(n, 1);
                    }
                }
            }
        };
        // The SAH cost, another pass over the binary nodes, is taken beside the
        // collapse (whose subtrees are tasks too). Then the binary BVH goes.
        let (wide, sah_cost) = rayon::join(
            || WideBvh::collapse(&bvh, 2 * LANES as u32, params),
            || bvh.sah_cost(params),
        );
        let collapsed = Mark::now();
        let mut summary = BvhSummary {
            nodes: bvh.nodes.len(),
            max_depth: bvh.max_depth,
            sah_cost,
            wide_nodes: 0,
            wide_sah_cost: 0.0,
            packets: 0,
            bounds: bvh
                .nodes
                .first()
                .map_or(Aabb::default(), |root| root.bounds()),
        };
        drop(bvh);
        let Packetized {
            wide,
            packets,
            shading,
        } = packetize(wide, order.len(), with_normals, is_sphere, prim_of, fetch);
        summary.wide_nodes = wide.nodes.len();
        summary.wide_sah_cost = wide.sah_cost(params, |packets| packets as Float);
        summary.packets = packets.len();

        // Texture coordinates only where a material can use them. An index out of
        // range (a description not made by a reader) counts as none.
        let textured = materials.iter().any(Material::needs_texcoords)
            && triangle_texcoords.iter().any(Option::is_some);
        let prim_texcoords: Vec<[u32; 3]> = if textured {
            let in_range = |ids: [u32; 3]| ids.iter().all(|&i| (i as usize) < texcoords.len());
            order
                .par_iter()
                .map(
                    |&i| match triangle_texcoords.get(i as usize).copied().flatten() {
                        Some(ids) if in_range(ids) => ids,
                        _ => [NO_TEXCOORDS; 3],
                    },
                )
                .collect()
        } else {
            Vec::new()
        };
        // Tangent indices in leaf order, only where some triangle has them (all of
        // which have texture coordinates, so the second phase reads them).
        let prim_tangents: Vec<[u32; 3]> = match vertex_tangents.corners.is_empty() {
            true => Vec::new(),
            false => (order.par_iter())
                .map(|&i| {
                    (vertex_tangents.corners.get(i as usize).copied())
                        .unwrap_or([super::tangents::NO_TANGENTS; 3])
                })
                .collect(),
        };
        let tangents = vertex_tangents.tangents;
        // Colours are interpolated by the second phase too.
        let second_phase = textured || !colours.is_empty();
        let texcoords = if textured { texcoords } else { Vec::new() };
        // Vertex colours by the corners' position indices, every position given one
        // (white past the description's last).
        let prim_colours: Vec<[u32; 3]> = if colours.is_empty() {
            Vec::new()
        } else {
            colours.resize(positions.len(), Vec3::ONE);
            (order.par_iter())
                .map(|&i| match triangles.get(i as usize) {
                    Some(t) => t.positions,
                    None => [NO_COLOURS; 3],
                })
                .collect()
        };
        let has_cutouts = materials.iter().any(|m| m.cutout().is_some());
        // A zero-length `vn` cannot be normalized: zero marks it, and the hit's
        // geometric normal stands in for it.
        let vertex_normals = normals
            .par_iter()
            .map(|&n| try_unit(n).unwrap_or(Vec3::ZERO))
            .collect();
        let built = Mark::now();
        let (tree, tree_usage) = started.to(&tree_built);
        let (collapse, collapse_usage) = tree_built.to(&collapsed);
        let (packets_time, packets_usage) = collapsed.to(&built);
        let build_times = BuildTimes {
            tree,
            collapse,
            packets: packets_time,
            usage: match (tree_usage, collapse_usage, packets_usage) {
                (Some(tree), Some(collapse), Some(packets)) => Some(BuildUsage {
                    tree,
                    collapse,
                    packets,
                }),
                _ => None,
            },
        };
        let radius = (bounds.max - bounds.min).length() * 0.5;
        let scene = Scene {
            unlit,
            environment,
            background,
            lit_by_rig,
            blend_in_layers: false,
            radius: if radius.is_finite() { radius } else { 0.0 },
            wide,
            packets,
            shading,
            vertex_normals,
            texcoords,
            source: order,
            objects,
            prim_texcoords,
            tangents,
            prim_tangents,
            second_phase,
            colours,
            prim_colours,
            has_cutouts,
            materials,
            lights,
            area_lights,
            summary,
            build_times,
            warnings,
            skipped,
            ray_by_ray: has_cutouts,
            instances: None,
        };
        (scene, meshes, instances)
    }
}

impl Scene {
    /// Warns of what the build skipped ([`Scene::skipped`]), and that nothing is left
    /// to render if `nothing_left`: once for the whole scene, after its levels.
    pub(super) fn warn_skipped(&mut self, nothing_left: bool) {
        self.warnings.extend(self.skipped.warnings());
        if nothing_left {
            self.warnings
                .push("the scene has no shapes left to render: every ray misses".into());
        }
    }
}

/// The shapes a level's build dropped: counted, so that a scene of several levels (a
/// glTF file's meshes used by several nodes) warns once with the totals.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Skipped {
    /// Triangles of zero area.
    pub(super) degenerate: usize,
    /// Copies of another shape.
    pub(super) duplicates: usize,
}

impl Skipped {
    /// The warnings that say what was skipped: none for nothing.
    pub(super) fn warnings(self) -> Vec<String> {
        let plural = |n: usize| if n == 1 { "" } else { "s" };
        let mut warnings = Vec::new();
        if self.duplicates > 0 {
            warnings.push(format!(
                "skipped {} duplicate shape{} (the same corners, normals, texture coordinates and material as another)",
                self.duplicates,
                plural(self.duplicates)
            ));
        }
        if self.degenerate > 0 {
            warnings.push(format!(
                "skipped {} degenerate (zero-area) triangle{}",
                self.degenerate,
                plural(self.degenerate)
            ));
        }
        warnings
    }

    /// Both counts added.
    pub(super) fn add(self, other: Skipped) -> Skipped {
        Skipped {
            degenerate: self.degenerate + other.degenerate,
            duplicates: self.duplicates + other.duplicates,
        }
    }
}

/// Marks in `coloured` (by material id) the materials of `level`'s triangles that
/// have a corner with a vertex colour.
fn mark_coloured_materials(level: &SceneDescription, coloured: &mut [bool]) {
    let given = level.colours.len();
    if given == 0 {
        return;
    }
    for t in &level.triangles {
        if t.positions.iter().any(|&p| (p as usize) < given)
            && let Some(c) = coloured.get_mut(t.material.0 as usize)
        {
            *c = true;
        }
    }
}

/// The emitting triangles and spheres of a description: those whose material has a
/// `Ke` with a positive mean (and an emission map that is not all black), with their
/// corners' texture coordinates where the material has an emission map. Scenes without
/// one (most) cost one pass over the materials.
fn collect_area_lights(
    description: (&[Vec3], &[Vec2]),
    triangles: &[TriangleDesc],
    triangle_texcoords: &[Option<[u32; 3]>],
    spheres: &[SphereDesc],
    materials: &[Material],
    (meshes, instances): (&[SceneDescription], &[InstanceDesc]),
) -> AreaLights {
    let (positions, texcoords) = description;
    let mut lights = AreaLightsBuilder::new(materials);
    if !lights.any_emits() {
        return lights.build();
    }
    let mapped = |id: MaterialId| {
        materials
            .get(id.0 as usize)
            .and_then(|m| m.maps.as_ref())
            .is_some_and(|m| m.emission.is_some())
    };
    for (i, t) in triangles.iter().enumerate() {
        // As `Scene::uv_at` gives them to hits: none (zero) when out of range.
        let uv = match triangle_texcoords.get(i).copied().flatten() {
            Some(ids) if mapped(t.material) => match ids.map(|k| texcoords.get(k as usize)) {
                [Some(&a), Some(&b), Some(&c)] => [a, b, c],
                _ => [Vec2::ZERO; 3],
            },
            _ => [Vec2::ZERO; 3],
        };
        lights.triangle(t.positions.map(|i| positions[i as usize]), uv, t.material);
    }
    for s in spheres {
        lights.sphere(s.center, s.radius, s.material);
    }
    // Every copy of an emitter, placed: a light sample then lands on the copy where
    // it is, with the copy's area (the mesh's emitting triangles listed once first).
    let emitting: Vec<Vec<usize>> = meshes
        .iter()
        .map(|mesh| {
            (mesh.triangles.iter().enumerate())
                .filter(|(_, t)| lights.emits(t.material))
                .map(|(i, _)| i)
                .collect()
        })
        .collect();
    for instance in instances {
        let (Some(mesh), Some(emitting)) = (
            meshes.get(instance.mesh as usize),
            emitting.get(instance.mesh as usize),
        ) else {
            continue;
        };
        for &i in emitting {
            let t = &mesh.triangles[i];
            let uv = match mesh.triangle_texcoords.get(i).copied().flatten() {
                Some(ids) if mapped(t.material) => {
                    match ids.map(|k| mesh.texcoords.get(k as usize)) {
                        [Some(&a), Some(&b), Some(&c)] => [a, b, c],
                        _ => [Vec2::ZERO; 3],
                    }
                }
                _ => [Vec2::ZERO; 3],
            };
            let [a, b, c] = t.positions.map(|p| {
                instance
                    .world_from_object
                    .transform_point3(mesh.positions[p as usize])
            });
            // A copy whose mirroring keeps its front emits from the same side.
            let (corners, uv) = if instance.winding_kept
                && instance.world_from_object.matrix3.determinant() < 0.0
            {
                ([a, c, b], [uv[0], uv[2], uv[1]])
            } else {
                ([a, b, c], uv)
            };
            lights.triangle(corners, uv, t.material);
        }
    }
    lights.build()
}

/// What [`packetize`] makes: the wide BVH, its packets, and the shading data of
/// every primitive in leaf order.
struct Packetized {
    wide: WideBvh,
    packets: Vec<TrianglePacket>,
    shading: ShadingData,
}

/// Points the leaves of `wide` (collapsed from the binary BVH, its leaves still
/// primitive ranges) at ranges of packets, and makes the packets of each leaf from its
/// primitives (`prim_of(prim)`, leaf order): triangles four by four, spheres apart.
/// The shading data `prim_of` gives is stored in the same pass, so the description
/// is gathered once. Leaves are filled in parallel, each into its own slices of the
/// packet and shading arrays; `is_sphere` counts a leaf's packets without making
/// its shapes.
fn packetize<S, F, P>(
    mut wide: WideBvh,
    prim_count: usize,
    with_normals: bool,
    is_sphere: S,
    prim_of: F,
    fetch: P,
) -> Packetized
where
    S: Fn(u32) -> bool + Sync,
    F: Fn(u32) -> (Shape, PrimShading) + Sync,
    P: Fn(u32, bool) + Sync,
{
    assert!(
        prim_count <= MAX_PRIM as usize + 1,
        "too many primitives for packet indices"
    );
    let leaves = wide.leaf_items();
    let packet_counts: Vec<u32> = leaves
        .par_iter()
        .map(|&(first, count)| {
            let spheres = (first..first + count)
                .filter(|&prim| is_sphere(prim))
                .count();
            ((count as usize - spheres).div_ceil(LANES) + spheres.div_ceil(LANES)) as u32
        })
        .collect();
    let mut first_packets = Vec::with_capacity(leaves.len() + 1);
    first_packets.push(0u32);
    for &count in &packet_counts {
        first_packets.push(first_packets.last().unwrap() + count);
    }
    let total = *first_packets.last().unwrap() as usize;

    // Each leaf writes its own ranges of the three arrays, so the writes (and the
    // page faults of the fresh arrays) are spread over all threads: its packets at
    // `first_packets[leaf]`, its shading data at its first primitive. Leaves list
    // their primitive ranges in node order, not in primitive order, so the ranges
    // are handed out as raw parts of the arrays, which only disjoint ranges make
    // sound: the leaves' primitive ranges must tile `0..prim_count` (collapse puts
    // every primitive in one leaf), which `assert_tiles` checks. (Cutting the
    // arrays into slices in primitive order took three per-leaf tables, 10 MB of
    // fresh memory on the dragon, written on one thread.)
    assert_tiles(&leaves, prim_count);
    let mut packets: Vec<TrianglePacket> = Vec::with_capacity(total);
    memory::advise_huge_pages(&packets);
    let mut materials: Vec<MaterialId> = Vec::with_capacity(prim_count);
    memory::advise_huge_pages(&materials);
    let normal_count = if with_normals { prim_count } else { 0 };
    let mut normals: Vec<[u32; 3]> = Vec::with_capacity(normal_count);
    memory::advise_huge_pages(&normals);
    let packet_parts = Parts::new(&mut packets.spare_capacity_mut()[..total]);
    let material_parts = Parts::new(&mut materials.spare_capacity_mut()[..prim_count]);
    let normal_parts = Parts::new(&mut normals.spare_capacity_mut()[..normal_count]);
    // Leaves in runs, so that each one's primitives are asked for ahead while the
    // leaves before them are written: their descriptions four leaves ahead, their
    // corners two leaves ahead (the description is in cache by then). The gather
    // waited on memory most of the time: on the dragon this step took 50-70 ms of
    // wall time under load, 25-30 ms with the hints (one and two leaves ahead
    // gave 40-50 ms, six and three 30-40 ms).
    leaves
        .par_chunks(LEAF_RUN)
        .enumerate()
        .for_each(|(run_index, run)| {
            let ask = |leaf: usize, corners: bool| {
                if let Some(&(first, count)) = run.get(leaf) {
                    for prim in first..first + count {
                        fetch(prim, corners);
                    }
                }
            };
            for leaf in 0..DESCRIPTIONS_AHEAD {
                ask(leaf, false);
            }
            for leaf in 0..CORNERS_AHEAD {
                ask(leaf, true);
            }
            for (leaf, &(first, count)) in run.iter().enumerate() {
                ask(leaf + DESCRIPTIONS_AHEAD, false);
                ask(leaf + CORNERS_AHEAD, true);
                let index = run_index * LEAF_RUN + leaf;
                let packet_range = first_packets[index] as usize..first_packets[index + 1] as usize;
                let prims = first as usize..(first + count) as usize;
                // SAFETY: the packet ranges are consecutive prefix sums, and the
                // primitive ranges tile `0..prim_count` (checked above): no two
                // leaves share an element of any of the three arrays.
                let (out, shading) = unsafe {
                    (
                        packet_parts.range(packet_range),
                        ShadingSlots {
                            materials: material_parts.range(prims.clone()),
                            normals: if with_normals {
                                normal_parts.range(prims)
                            } else {
                                &mut []
                            },
                        },
                    )
                };
                write_leaf(first, count, &prim_of, out, shading);
            }
        });
    // SAFETY: the packet ranges cover `0..total` exactly, the primitive ranges
    // `0..prim_count`, and `write_leaf` wrote every element of its ranges (it
    // asserts so).
    unsafe {
        packets.set_len(total);
        materials.set_len(prim_count);
        normals.set_len(normal_count);
    }
    wide.assign_leaf_items(&first_packets);
    Packetized {
        wide,
        packets,
        shading: ShadingData { materials, normals },
    }
}

/// Panics unless the ranges `(first, count)` tile `0..prim_count`: none empty, none
/// overlapping, no gap.
///
/// Without a sort (which took 1-2 ms of the dragon's build): with one bit per
/// primitive marking where ranges start, the ranges must be non-empty and inside
/// `0..prim_count`, start at distinct places, one of them at 0, each end where
/// another starts (or at `prim_count`), and hold `prim_count` primitives together.
/// Then the ranges chained from 0 tile `0..prim_count`, and they alone already hold
/// every primitive, so no other range is left to overlap them.
fn assert_tiles(ranges: &[(u32, u32)], prim_count: usize) {
    let tiles = || {
        let mut starts = vec![0u64; prim_count.div_ceil(64) + 1];
        let is_start = |starts: &[u64], at: usize| starts[at / 64] >> (at % 64) & 1 != 0;
        let mut total = 0usize;
        for &(first, count) in ranges {
            let (first, count) = (first as usize, count as usize);
            if count == 0 || first >= prim_count || count > prim_count - first {
                return false;
            }
            if is_start(&starts, first) {
                return false;
            }
            starts[first / 64] |= 1 << (first % 64);
            total += count;
        }
        total == prim_count
            && (prim_count == 0 || is_start(&starts, 0))
            && ranges.iter().all(|&(first, count)| {
                let end = first as usize + count as usize;
                end == prim_count || is_start(&starts, end)
            })
    };
    assert!(tiles(), "leaves do not tile the primitives");
}

/// An array's spare capacity, handed out in ranges to the threads that write them
/// (see [`packetize`]).
struct Parts<T> {
    start: *mut MaybeUninit<T>,
    len: usize,
}

// SAFETY: `Parts` only hands out ranges, each to one thread (the caller's contract
// of `Parts::range`); `T` is written from those threads.
unsafe impl<T: Send> Sync for Parts<T> {}

impl<T> Parts<T> {
    fn new(slots: &mut [MaybeUninit<T>]) -> Parts<T> {
        Parts {
            start: slots.as_mut_ptr(),
            len: slots.len(),
        }
    }

    /// The slots of `range`.
    ///
    /// # Safety
    /// No two calls may hand out overlapping ranges while both are in use.
    #[allow(clippy::mut_from_ref)]
    unsafe fn range(&self, range: std::ops::Range<usize>) -> &mut [MaybeUninit<T>] {
        assert!(
            range.start <= range.end && range.end <= self.len,
            "range out of bounds"
        );
        // SAFETY: inside the slots `new` took; not aliased, by the caller's contract.
        unsafe { std::slice::from_raw_parts_mut(self.start.add(range.start), range.len()) }
    }
}

/// One leaf's slots of the shading data: a material per primitive, and its
/// normals' indices per primitive or none (a scene without vertex normals).
struct ShadingSlots<'a> {
    materials: &'a mut [MaybeUninit<MaterialId>],
    normals: &'a mut [MaybeUninit<[u32; 3]>],
}

/// Leaves written in a row by one thread in [`packetize`].
const LEAF_RUN: usize = 256;

/// How many leaves ahead [`packetize`] asks for the primitives' descriptions.
const DESCRIPTIONS_AHEAD: usize = 4;

/// How many leaves ahead [`packetize`] asks for the triangles' corners.
const CORNERS_AHEAD: usize = 2;

/// Writes the packets of the leaf holding primitives `first..first + count` into
/// `out`, which must have room for exactly as many as it needs, and their shading
/// data into `shading` (a material per primitive, and the normals' indices per
/// primitive unless its normal slots are empty).
fn write_leaf<F>(
    first: u32,
    count: u32,
    prim_of: &F,
    out: &mut [MaybeUninit<TrianglePacket>],
    shading: ShadingSlots<'_>,
) where
    F: Fn(u32) -> (Shape, PrimShading),
{
    assert_eq!(
        shading.materials.len(),
        count as usize,
        "material slots of a leaf"
    );
    let with_normals = !shading.normals.is_empty();
    assert!(
        !with_normals || shading.normals.len() == count as usize,
        "normal slots of a leaf"
    );
    let mut written = 0;
    let mut emit = |packet: TrianglePacket| {
        out[written].write(packet);
        written += 1;
    };
    let zero = Triangle::new(Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
    let mut triangles = [(0u32, zero); LANES];
    let mut triangle_count = 0;
    let mut spheres = [(
        0u32,
        Sphere {
            center: Vec3::ZERO,
            radius: 0.0,
        },
    ); LANES];
    let mut sphere_count = 0;
    for (i, prim) in (first..first + count).enumerate() {
        let (shape, prim_shading) = prim_of(prim);
        shading.materials[i].write(prim_shading.material);
        if with_normals {
            shading.normals[i].write(prim_shading.normals);
        }
        match shape {
            Shape::Triangle(tri) => {
                triangles[triangle_count] = (prim, tri);
                triangle_count += 1;
                if triangle_count == LANES {
                    emit(TrianglePacket::new(&triangles));
                    triangle_count = 0;
                }
            }
            Shape::Sphere(sphere) => {
                spheres[sphere_count] = (prim, sphere);
                sphere_count += 1;
                if sphere_count == LANES {
                    emit(TrianglePacket::spheres(&spheres));
                    sphere_count = 0;
                }
            }
        }
    }
    if triangle_count > 0 {
        emit(TrianglePacket::new(&triangles[..triangle_count]));
    }
    if sphere_count > 0 {
        emit(TrianglePacket::spheres(&spheres[..sphere_count]));
    }
    assert_eq!(written, out.len(), "packet count of a leaf");
}

#[cfg(test)]
mod build_tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use std::collections::HashMap;

    /// A scene whose triangles have no vertex normals keeps a material per
    /// primitive and no normal indices at all; one whose triangles have them keeps
    /// them for every primitive, and each primitive reads back the same shading
    /// data either way.
    #[test]
    fn normal_indices_are_kept_only_for_scenes_with_vertex_normals() {
        let with = packet::tests::generated_description(20, true, 3);
        let mut without = with.clone();
        without.normals.clear();
        without.triangle_normals.clear();
        let (with, without) = (
            Scene::build(with, &BvhParams::default()),
            Scene::build(without, &BvhParams::default()),
        );
        assert_eq!(with.shading.normals.len(), with.prim_count());
        assert!(without.shading.normals.is_empty());
        assert_eq!(without.shading.materials.len(), without.prim_count());
        let mut with_corner_normals = 0;
        for prim in 0..with.prim_count() as u32 {
            let (a, b) = (with.shading.get(prim), without.shading.get(prim));
            assert_eq!(a.material, b.material);
            assert_eq!(b.normals, [NO_NORMALS; 3]);
            with_corner_normals += usize::from(a.normals != [NO_NORMALS; 3]);
        }
        assert!(with_corner_normals > 0);
    }

    /// The packets step hands each leaf its ranges of the arrays only if the leaves
    /// tile the primitives.
    #[test]
    fn leaves_must_tile_the_primitives() {
        assert_tiles(&[(4, 3), (0, 4), (7, 1)], 8);
        assert_tiles(&[], 0);
        let many: Vec<(u32, u32)> = (0..1000).rev().map(|i| (3 * i, 3)).collect();
        assert_tiles(&many, 3000);
        for (ranges, prim_count) in [
            (&[(0, 4), (3, 5)][..], 8),               // overlap
            (&[(0, 4), (5, 3)][..], 8),               // gap
            (&[(0, 4), (4, 0), (4, 4)][..], 8),       // empty leaf
            (&[(0, 4)][..], 8),                       // short
            (&[(0, 4), (4, 4)][..], 7),               // long
            (&[(0, u32::MAX), (u32::MAX, 2)][..], 3), // wraps
            (&[(0, 4), (0, 4)][..], 8),               // the same leaf twice
            (&[(1, 1), (2, 2), (3, 1)][..], 4),       // chained, but not from 0
            (&[(0, 1)][..], 0),                       // no primitives
        ] {
            let result = std::panic::catch_unwind(|| assert_tiles(ranges, prim_count));
            assert!(result.is_err(), "{ranges:?} over {prim_count}");
        }
    }

    /// The build's steps are timed one after another inside it: together they take
    /// no longer than the whole build timed from outside, and a build over shapes
    /// spends its time in them (not all of it in one). Their CPU time and faults,
    /// read from the process's counters, likewise add up to no more than the
    /// counters moved over the whole build (other tests' threads count in both).
    #[test]
    fn build_steps_are_timed_in_turn_within_the_build() {
        let description = packet::tests::generated_description(60, true, 7);
        let started = Mark::now();
        let scene = Scene::build(description, &BvhParams::default());
        let (whole, usage_whole) = started.to(&Mark::now());
        let steps = scene.build_times();
        assert!(
            steps.tree + steps.collapse + steps.packets <= whole,
            "{steps:?} beyond {whole:?}"
        );
        assert!(steps.tree > std::time::Duration::ZERO, "{steps:?}");
        assert!(steps.packets > std::time::Duration::ZERO, "{steps:?}");
        if cfg!(unix) {
            let usage = steps.usage.expect("Unix reports usage");
            let whole = usage_whole.expect("Unix reports usage");
            let parts = [usage.tree, usage.collapse, usage.packets];
            let cpu: std::time::Duration = parts.iter().map(|u| u.cpu).sum();
            let faults: u64 = parts.iter().map(|u| u.minor_faults).sum();
            assert!(cpu <= whole.cpu, "{usage:?} beyond {whole:?}");
            assert!(faults <= whole.minor_faults, "{usage:?} beyond {whole:?}");
            assert!(usage.tree.cpu > std::time::Duration::ZERO, "{usage:?}");
        }
    }

    /// The shading data is written leaf by leaf beside the packets, into slices cut
    /// in primitive order and handed to leaves listed in node order: every primitive
    /// must get the material and normals of the shape its packet lane holds. Each
    /// triangle and sphere here has a material (and a triangle its normals) of its
    /// own, found again through its first corner or centre.
    #[test]
    fn shading_data_belongs_to_the_primitive_of_its_lane() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(14);
        let mut d = SceneDescription::default();
        let triangles = 3000;
        let spheres = 60;
        let mut material_of_corner = HashMap::new();
        for t in 0..triangles {
            let a = Vec3::new(rng.random(), rng.random(), rng.random()) * 10.0;
            let corners = [
                a,
                a + Vec3::new(0.1, 0.0, 0.0),
                a + Vec3::new(0.0, 0.1, 0.05),
            ];
            let first = d.positions.len() as u32;
            d.positions.extend(corners);
            d.normals.extend([Vec3::Y; 3]);
            let material = MaterialId(t);
            material_of_corner.insert(a.to_array().map(f32::to_bits), (material, first));
            d.push_triangle(
                TriangleDesc {
                    positions: [first, first + 1, first + 2],
                    material,
                },
                Some([first, first + 1, first + 2]),
            );
        }
        let mut material_of_centre = HashMap::new();
        for s in 0..spheres {
            let center = Vec3::new(rng.random(), rng.random(), rng.random()) * 10.0;
            let material = MaterialId(triangles + s);
            material_of_centre.insert(center.to_array().map(f32::to_bits), material);
            d.spheres.push(SphereDesc {
                center,
                radius: 0.05,
                material,
            });
        }
        d.materials = vec![Material::fallback(); (triangles + spheres) as usize];
        let scene = Scene::build(d, &BvhParams::default());
        scene.validate().unwrap();
        let mut checked = 0;
        for packet in &scene.packets {
            for lane in 0..LANES {
                let (Some(prim), Some(shape)) = (packet.prim(lane), packet.shape(lane)) else {
                    continue;
                };
                let shading = scene.shading.get(prim);
                match shape {
                    Shape::Triangle(t) => {
                        let (material, first) =
                            material_of_corner[&t.v0.to_array().map(f32::to_bits)];
                        assert_eq!(shading.material, material);
                        assert_eq!(shading.normals, [first, first + 1, first + 2]);
                    }
                    Shape::Sphere(s) => {
                        let material = material_of_centre[&s.center.to_array().map(f32::to_bits)];
                        assert_eq!(shading.material, material);
                        assert_eq!(shading.normals, [NO_NORMALS; 3]);
                    }
                }
                checked += 1;
            }
        }
        assert_eq!(checked, triangles + spheres);
    }

    /// [`Scene::source_index`] names the description's triangle a ray hits, past
    /// the degenerate triangles the build drops, with the spheres after the
    /// triangles: here a grid of triangles side by side in the plane `z = 0`, listed
    /// in shuffled order, each hit from straight above its centroid.
    #[test]
    fn source_index_names_the_description_primitive() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(25);
        let mut cells: Vec<(u32, u32, bool)> = (0..30)
            .flat_map(|x| (0..30).flat_map(move |y| [(x, y, false), (x, y, true)]))
            .collect();
        for i in (1..cells.len()).rev() {
            cells.swap(i, rng.random_range(0..=i));
        }
        let mut d = SceneDescription::default();
        let mut centroids = Vec::new();
        for (i, &(x, y, upper)) in cells.iter().enumerate() {
            let (x, y) = (x as f32, y as f32);
            let corners = if upper {
                [
                    Vec3::new(x + 1.0, y, 0.0),
                    Vec3::new(x + 1.0, y + 1.0, 0.0),
                    Vec3::new(x, y + 1.0, 0.0),
                ]
            } else {
                [
                    Vec3::new(x, y, 0.0),
                    Vec3::new(x + 1.0, y, 0.0),
                    Vec3::new(x, y + 1.0, 0.0),
                ]
            };
            if i % 7 == 3 {
                // A zero-area triangle before this one: dropped, but it keeps its index.
                let first = d.positions.len() as u32;
                d.positions.extend([corners[0]; 3]);
                d.triangles.push(TriangleDesc {
                    positions: [first, first + 1, first + 2],
                    material: MaterialId(0),
                });
                centroids.push(None);
            }
            let first = d.positions.len() as u32;
            d.positions.extend(corners);
            d.triangles.push(TriangleDesc {
                positions: [first, first + 1, first + 2],
                material: MaterialId(0),
            });
            centroids.push(Some((corners[0] + corners[1] + corners[2]) / 3.0));
        }
        d.spheres.push(SphereDesc {
            center: Vec3::new(-5.0, -5.0, 0.0),
            radius: 1.0,
            material: MaterialId(0),
        });
        centroids.push(Some(Vec3::new(-5.0, -5.0, 0.0)));
        d.materials = vec![Material::fallback()];
        let scene = Scene::build(d, &BvhParams::default());
        assert!(scene.warnings.iter().any(|w| w.contains("degenerate")));
        let mut checked = 0;
        for (index, centroid) in centroids.iter().enumerate() {
            let Some(centroid) = centroid else { continue };
            let ray = Ray::new(*centroid + Vec3::new(0.0, 0.0, 3.0), -Vec3::Z);
            let (prim, _) = scene.intersect_primitive(&ray).expect("the ray hits");
            assert_eq!(
                scene.source_index(prim),
                index,
                "primitive hit above {centroid}"
            );
            checked += 1;
        }
        assert_eq!(checked, scene.prim_count());
    }
}
