//! BVH build and traversal at several sizes against the linear scan, with seeded rays
//! (as the `bvh` crate measures at 1.2K/12K/120K triangles), plus the deer mesh.
//! Reports SAH cost as a quality number. Run with `cargo bench --bench bvh`.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use rand::{Rng, SeedableRng};
use raytracer::description::{SceneDescription, TriangleDesc};
use raytracer::math::{Ray, Vec3};
use raytracer::{BvhParams, MaterialId, Scene};

type Rng64 = rand::rngs::StdRng;

const RAYS: usize = 1024;

fn random_vec(rng: &mut Rng64, scale: f32) -> Vec3 {
    Vec3::new(
        rng.random_range(-scale..scale),
        rng.random_range(-scale..scale),
        rng.random_range(-scale..scale),
    )
}

/// `n` small random triangles in a cube of side 20.
fn soup(n: usize) -> SceneDescription {
    let mut rng = Rng64::seed_from_u64(n as u64);
    let mut d = SceneDescription::default();
    for i in 0..n as u32 {
        let center = random_vec(&mut rng, 10.0);
        for _ in 0..3 {
            d.positions.push(center + random_vec(&mut rng, 0.3));
        }
        d.triangles.push(TriangleDesc {
            positions: [3 * i, 3 * i + 1, 3 * i + 2],
            material: MaterialId(0),
        });
    }
    d
}

fn deer() -> SceneDescription {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/reference/scenes/deer/CERF_Free.obj"
    );
    raytracer::formats::load_obj(path.as_ref()).expect("the deer fixture")
}

/// Rays from outside towards random points of the scene's middle.
fn rays(seed: u64, scale: f32) -> Vec<Ray> {
    let mut rng = Rng64::seed_from_u64(seed);
    (0..RAYS)
        .map(|_| {
            let origin = random_vec(&mut rng, 1.0).normalize() * scale * 2.0;
            Ray::new(origin, random_vec(&mut rng, scale * 0.5) - origin)
        })
        .collect()
}

fn benches(c: &mut Criterion) {
    let params = BvhParams::default();
    let cases: Vec<(String, SceneDescription, f32, Vec3)> = vec![
        ("soup-1.2k".into(), soup(1_200), 10.0, Vec3::ZERO),
        ("soup-12k".into(), soup(12_000), 10.0, Vec3::ZERO),
        ("soup-120k".into(), soup(120_000), 10.0, Vec3::ZERO),
        ("deer".into(), deer(), 100.0, Vec3::new(0.0, 100.0, 0.0)),
    ];

    let mut build = c.benchmark_group("bvh-build");
    build.sample_size(10);
    for (name, description, _, _) in &cases {
        build.throughput(Throughput::Elements(description.triangles.len() as u64));
        build.bench_with_input(BenchmarkId::from_parameter(name), description, |b, d| {
            b.iter(|| Scene::build(black_box(d.clone()), &params))
        });
    }
    build.finish();

    let mut trace = c.benchmark_group("closest-hit");
    trace.throughput(Throughput::Elements(RAYS as u64));
    for (name, description, scale, center) in &cases {
        let scene = Scene::build(description.clone(), &params);
        eprintln!(
            "{name}: SAH cost {:.2}, {} nodes",
            scene.bvh_summary().sah_cost,
            scene.bvh_summary().nodes
        );
        let rays: Vec<Ray> = rays(7, *scale)
            .into_iter()
            .map(|r| Ray::new(r.origin + *center, r.dir))
            .collect();
        trace.bench_function(BenchmarkId::new("bvh", name), |b| {
            b.iter(|| rays.iter().filter(|r| scene.intersect(r).is_some()).count())
        });
        trace.bench_function(BenchmarkId::new("any-hit", name), |b| {
            b.iter(|| {
                rays.iter()
                    .filter(|r| scene.occluded(r, f32::INFINITY))
                    .count()
            })
        });
        // The linear scan is the baseline; past 12k triangles it takes too long to
        // sample and says nothing new.
        if description.triangles.len() <= 12_000 {
            trace.bench_function(BenchmarkId::new("linear", name), |b| {
                b.iter(|| {
                    rays.iter()
                        .filter(|r| scene.intersect_linear(r).is_some())
                        .count()
                })
            });
        }
    }
    trace.finish();
}

criterion_group!(bvh, benches);
criterion_main!(bvh);
