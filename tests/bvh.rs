//! The BVH against brute force: for thousands of seeded rays on random triangle
//! soups, sphere sets and the deer mesh, the BVH's closest hit equals the linear
//! scan's, any-hit agrees with closest-hit, and `Bvh::validate` holds.

use crate::support;

use proptest::prelude::*;
use proptest::test_runner::Config;
use rand::{Rng, SeedableRng};
use raytracer::bvh::{Bvh, BvhParams};
use raytracer::description::{SceneDescription, SphereDesc, TriangleDesc};
use raytracer::math::{Aabb, Ray, Vec3};
use raytracer::{MaterialId, Scene, formats};

type Rng64 = rand::rngs::StdRng;

fn random_vec(rng: &mut Rng64, scale: f32) -> Vec3 {
    Vec3::new(
        rng.random_range(-scale..scale),
        rng.random_range(-scale..scale),
        rng.random_range(-scale..scale),
    )
}

fn random_soup(rng: &mut Rng64, triangles: usize, spheres: usize) -> SceneDescription {
    let mut d = SceneDescription::default();
    for _ in 0..triangles {
        let center = random_vec(rng, 10.0);
        let size = rng.random_range(0.01..2.0);
        let base = d.positions.len() as u32;
        for _ in 0..3 {
            d.positions.push(center + random_vec(rng, size));
        }
        d.triangles.push(TriangleDesc {
            positions: [base, base + 1, base + 2],
            material: MaterialId(0),
        });
    }
    for _ in 0..spheres {
        d.spheres.push(SphereDesc {
            center: random_vec(rng, 10.0),
            radius: rng.random_range(0.01..1.5),
            material: MaterialId(0),
        });
    }
    d
}

/// Rays from random points, half of them aimed at random points of the scene's box
/// and a few exactly axis-parallel.
fn random_rays(rng: &mut Rng64, count: usize, scale: f32) -> Vec<Ray> {
    (0..count)
        .map(|i| {
            let origin = random_vec(rng, scale * 1.5);
            let dir = match i % 8 {
                0 => Vec3::X,
                1 => Vec3::NEG_Y,
                2 => Vec3::Z,
                3..=5 => random_vec(rng, scale) - origin,
                _ => random_vec(rng, 1.0),
            };
            Ray::new(origin, if dir.length() > 1e-3 { dir } else { Vec3::Y })
        })
        .collect()
}

fn assert_bvh_matches_linear(scene: &Scene, rays: &[Ray]) {
    scene.validate().unwrap();
    let mut hits = 0;
    for ray in rays {
        let fast = scene.intersect(ray);
        let slow = scene.intersect_linear(ray);
        match (fast, slow) {
            (Some(a), Some(b)) => {
                hits += 1;
                // Both run the same kernel arithmetic (the SIMD leaves lane for lane),
                // so the distances agree to the bit unless the BVH culled a box wrongly.
                assert!(
                    a.t == b.t,
                    "closest hit differs for {ray:?}: {} vs {}",
                    a.t,
                    b.t
                );
                assert!(scene.occluded(ray, a.t * 1.0001 + 1e-4));
                assert!(!scene.occluded(ray, a.t * 0.9999 - 1e-4) || a.t < 2e-4);
            }
            (None, None) => assert!(!scene.occluded(ray, f32::INFINITY)),
            (a, b) => panic!("BVH and linear scan disagree for {ray:?}: {a:?} vs {b:?}"),
        }
    }
    if scene.prim_count() >= 1000 {
        assert!(
            hits > rays.len() / 20,
            "too few hits ({hits}) to mean anything"
        );
    }
}

#[test]
fn bvh_equals_linear_scan_on_random_soups() {
    let mut rng = Rng64::seed_from_u64(7);
    for (triangles, spheres) in [
        (1, 0),
        (2, 1),
        (100, 0),
        (1000, 20),
        (5000, 100),
        (40_000, 0),
    ] {
        let scene = Scene::build(
            random_soup(&mut rng, triangles, spheres),
            &BvhParams::default(),
        );
        let rays = random_rays(&mut rng, 2000, 10.0);
        assert_bvh_matches_linear(&scene, &rays);
    }
}

#[test]
fn bvh_equals_linear_scan_on_the_deer() {
    let path = support::reference_dir().join("scenes/deer/CERF_Free.obj");
    let scene = Scene::build(formats::load_obj(&path).unwrap(), &BvhParams::default());
    let mut rng = Rng64::seed_from_u64(11);
    let center = Vec3::new(0.0, 100.0, 0.0);
    let rays: Vec<Ray> = (0..3000)
        .map(|_| {
            let origin = center + random_vec(&mut rng, 200.0);
            let target = center + random_vec(&mut rng, 60.0);
            Ray::new(origin, target - origin)
        })
        .collect();
    assert_bvh_matches_linear(&scene, &rays);
}

#[test]
fn parallel_build_is_valid_and_matches_sequential_hits() {
    let mut rng = Rng64::seed_from_u64(3);
    let soup = random_soup(&mut rng, 30_000, 0);
    let parallel = BvhParams {
        parallel_threshold: 1024,
        ..BvhParams::default()
    };
    let sequential = BvhParams {
        parallel_threshold: usize::MAX,
        ..BvhParams::default()
    };
    // The binary trees themselves, as the scene builds them before collapsing.
    let boxes: Vec<Aabb> = soup
        .triangles
        .iter()
        .map(|t| Aabb::from_points(&t.positions.map(|i| soup.positions[i as usize])))
        .collect();
    for params in [&parallel, &sequential] {
        let (bvh, order) = Bvh::build(&boxes, params);
        let ordered: Vec<Aabb> = order.iter().map(|&i| boxes[i as usize]).collect();
        bvh.validate(&ordered).unwrap();
    }
    let a = Scene::build(soup.clone(), &parallel);
    let b = Scene::build(soup, &sequential);
    a.validate().unwrap();
    b.validate().unwrap();
    assert_eq!(a.bvh_summary(), b.bvh_summary());
    for ray in random_rays(&mut rng, 2000, 10.0) {
        assert_eq!(
            a.intersect(&ray).map(|h| h.t),
            b.intersect(&ray).map(|h| h.t)
        );
    }
}

/// Random boxes of all sizes, for building without a scene.
fn random_boxes(rng: &mut Rng64, count: usize) -> Vec<Aabb> {
    (0..count)
        .map(|_| {
            let center = random_vec(rng, 10.0);
            let half = random_vec(rng, 0.5).abs();
            Aabb {
                min: center - half,
                max: center + half,
            }
        })
        .collect()
}

#[test]
fn the_tree_is_the_same_for_any_thread_count() {
    // Small blocks so that binning, partitioning and dropping primitives all run
    // in parallel pieces; every 7th primitive is dropped.
    let boxes = random_boxes(&mut Rng64::seed_from_u64(21), 40_000);
    let params = BvhParams {
        parallel_threshold: 1024,
        ..BvhParams::default()
    };
    let build_on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            Bvh::build_filtered(boxes.len(), |i| (i % 7 != 3).then_some(boxes[i]), &params)
        })
    };
    let (one, one_order) = build_on(1);
    for threads in [2, 3] {
        let (bvh, order) = build_on(threads);
        assert_eq!(bvh.nodes, one.nodes, "nodes on {threads} threads");
        assert_eq!(order, one_order, "leaf order on {threads} threads");
        assert_eq!(bvh.max_depth, one.max_depth);
    }
}

#[test]
fn filtered_builds_leave_out_exactly_the_dropped_primitives() {
    let boxes = random_boxes(&mut Rng64::seed_from_u64(22), 50_000);
    // Drops in the first block, a whole run across a block boundary, and the last.
    let keep = |i: usize| !i.is_multiple_of(3) && !(16_000..17_000).contains(&i) && i != 49_999;
    let (bvh, order) = Bvh::build_filtered(
        boxes.len(),
        |i| keep(i).then_some(boxes[i]),
        &BvhParams::default(),
    );
    let mut sorted = order.clone();
    sorted.sort_unstable();
    let kept: Vec<u32> = (0..boxes.len() as u32)
        .filter(|&i| keep(i as usize))
        .collect();
    assert_eq!(sorted, kept);
    let ordered: Vec<Aabb> = order.iter().map(|&i| boxes[i as usize]).collect();
    bvh.validate(&ordered).unwrap();
    // Dropping everything leaves an empty tree.
    let (bvh, order) = Bvh::build_filtered(1000, |_| None, &BvhParams::default());
    assert!(bvh.nodes.is_empty() && order.is_empty());
}

#[test]
fn degenerate_inputs_build_valid_trees() {
    // Nothing at all.
    let (bvh, order) = Bvh::build(&[], &BvhParams::default());
    assert!(bvh.nodes.is_empty() && order.is_empty());
    bvh.validate(&[]).unwrap();
    // One primitive; many with the same centroid; a flat (zero-thickness) layer.
    let unit = Aabb {
        min: Vec3::ZERO,
        max: Vec3::ONE,
    };
    let flat: Vec<Aabb> = (0..1000)
        .map(|i| {
            let x = i as f32;
            Aabb {
                min: Vec3::new(x, 0.0, 0.0),
                max: Vec3::new(x + 1.0, 0.0, 1.0),
            }
        })
        .collect();
    for boxes in [vec![unit], vec![unit; 10_000], flat] {
        let params = BvhParams::default();
        let (bvh, order) = Bvh::build(&boxes, &params);
        let ordered: Vec<Aabb> = order.iter().map(|&i| boxes[i as usize]).collect();
        bvh.validate(&ordered).unwrap();
        assert!(
            bvh.nodes
                .iter()
                .all(|n| !n.is_leaf() || n.prim_count as usize <= params.max_leaf_size)
        );
    }
}

#[test]
fn rays_starting_inside_the_root_box_and_axis_parallel_rays_hit() {
    let mut rng = Rng64::seed_from_u64(5);
    let scene = Scene::build(random_soup(&mut rng, 2000, 10), &BvhParams::default());
    let rays: Vec<Ray> = (0..2000)
        .map(|i| {
            let dir = [
                Vec3::X,
                Vec3::NEG_X,
                Vec3::Y,
                Vec3::NEG_Y,
                Vec3::Z,
                Vec3::NEG_Z,
            ][i % 6];
            Ray::new(random_vec(&mut rng, 5.0), dir)
        })
        .collect();
    assert_bvh_matches_linear(&scene, &rays);
}

proptest! {
    #![proptest_config(Config { cases: 64, ..Config::default() })]
    #[test]
    fn any_seeded_soup_agrees_with_linear_scan(seed in any::<u64>(), n in 1usize..300) {
        let mut rng = Rng64::seed_from_u64(seed);
        let scene = Scene::build(random_soup(&mut rng, n, n / 10), &BvhParams::default());
        scene.validate().unwrap();
        for ray in random_rays(&mut rng, 100, 10.0) {
            let a = scene.intersect(&ray).map(|h| h.t);
            let b = scene.intersect_linear(&ray).map(|h| h.t);
            prop_assert_eq!(a.is_some(), b.is_some());
            if let (Some(a), Some(b)) = (a, b) {
                prop_assert!((a - b).abs() <= 1e-5 * a.max(1.0));
            }
        }
    }
}

#[test]
fn piles_of_coinciding_centroids_are_reported_as_ranges() {
    let unit = Aabb {
        min: Vec3::ZERO,
        max: Vec3::ONE,
    };
    let params = BvhParams::default();
    // More than a leaf holds: one range over all of them, none nested in it.
    let (bvh, _) = Bvh::build(&[unit; 20], &params);
    assert_eq!(bvh.coincident, vec![0..20]);
    // A leaf's worth: no range.
    let (bvh, _) = Bvh::build(&[unit; 8], &params);
    assert!(bvh.coincident.is_empty());
    // A big pile beside other boxes, built in parallel: the pile's range.
    let mut boxes = vec![unit; 100_000];
    boxes.extend((1..=50).map(|k| Aabb {
        min: Vec3::splat(k as f32 * 2.0),
        max: Vec3::splat(k as f32 * 2.0 + 1.0),
    }));
    let (bvh, order) = Bvh::build(&boxes, &params);
    assert_eq!(bvh.coincident.len(), 1, "{:?}", bvh.coincident);
    let range = bvh.coincident[0].clone();
    assert_eq!(range.len(), 100_000);
    assert!(
        order[range.start as usize..range.end as usize]
            .iter()
            .all(|&i| i < 100_000)
    );
    // Distinct boxes: none.
    let (bvh, _) = Bvh::build(&boxes[100_000..], &params);
    assert!(bvh.coincident.is_empty());
}

/// A bumpy height field of `cells` x `cells` quads, two triangles each: a surface
/// like the meshes people render, where leaves of whole packets are possible.
fn height_field(cells: u32) -> SceneDescription {
    let mut d = SceneDescription::default();
    for j in 0..=cells {
        for i in 0..=cells {
            let (x, z) = (i as f32 / cells as f32, j as f32 / cells as f32);
            let y = 0.1 * (7.0 * x).sin() * (5.0 * z).cos();
            d.positions.push(Vec3::new(x, y, z));
        }
    }
    let at = |i: u32, j: u32| j * (cells + 1) + i;
    for j in 0..cells {
        for i in 0..cells {
            for positions in [
                [at(i, j), at(i + 1, j), at(i + 1, j + 1)],
                [at(i, j), at(i + 1, j + 1), at(i, j + 1)],
            ] {
                d.triangles.push(TriangleDesc {
                    positions,
                    material: MaterialId(0),
                });
            }
        }
    }
    d
}

#[test]
fn the_sah_prices_leaves_in_packets_and_fills_them() {
    let per_primitive = BvhParams {
        block_size: 1,
        min_leaf_size: 1,
        ..BvhParams::default()
    };
    let deer =
        formats::load_obj(&support::reference_dir().join("scenes/deer/CERF_Free.obj")).unwrap();
    for (name, mesh) in [("height field", height_field(100)), ("deer", deer)] {
        let triangles = mesh.triangles.len();
        let blocks = Scene::build(mesh.clone(), &BvhParams::default());
        let singles = Scene::build(mesh, &per_primitive);
        let (blocks, singles) = (blocks.bvh_summary().packets, singles.bvh_summary().packets);
        eprintln!("{name}: {triangles} triangles, packets {blocks} with blocks, {singles} without");
        assert!(blocks < singles, "{name}");
    }
}

#[test]
fn nodes_of_at_most_min_leaf_size_primitives_are_leaves() {
    let boxes = random_boxes(&mut Rng64::seed_from_u64(23), 20_000);
    for min_leaf_size in [1, 4, 8] {
        let params = BvhParams {
            min_leaf_size,
            ..BvhParams::default()
        };
        let (bvh, _) = Bvh::build(&boxes, &params);
        fn count(bvh: &Bvh, index: usize, small_interior: &mut usize, min: usize) -> usize {
            let node = &bvh.nodes[index];
            if node.is_leaf() {
                return node.prim_count as usize;
            }
            let first = node.first_index as usize;
            let n =
                count(bvh, first, small_interior, min) + count(bvh, first + 1, small_interior, min);
            *small_interior += usize::from(n <= min);
            n
        }
        let mut small_interior = 0;
        assert_eq!(
            count(&bvh, 0, &mut small_interior, min_leaf_size),
            boxes.len()
        );
        assert_eq!(small_interior, 0, "min_leaf_size {min_leaf_size}");
        if min_leaf_size == 1 {
            // Without the rule the SAH splits some small nodes: the test can fail.
            let mut below_eight = 0;
            count(&bvh, 0, &mut below_eight, 8);
            assert!(below_eight > 0);
        }
    }
}
