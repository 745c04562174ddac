//! Seeded property tests for the classic ray-tracer bugs (after pbrt's
//! `Triangle.Watertight` and `Reintersect`): a ray spawned from a hit must not hit
//! the surface it leaves, and rays from inside a closed mesh must always hit it.

use rand::{Rng, SeedableRng};
use raytracer::description::{SceneDescription, SphereDesc, TriangleDesc};
use raytracer::math::{Ray, Vec3};
use raytracer::{BvhParams, MaterialId, Scene};

type Rng64 = rand::rngs::StdRng;

fn unit_vector(rng: &mut Rng64) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
            return v.normalize();
        }
    }
}

fn build(description: SceneDescription) -> Scene {
    Scene::build(description, &BvhParams::default())
}

/// A closed UV sphere of `rings` x `segments` quads with shared vertices, each
/// vertex pushed radially by a random factor.
fn perturbed_sphere_mesh(
    rng: &mut Rng64,
    center: Vec3,
    radius: f32,
    rings: u32,
    segments: u32,
) -> SceneDescription {
    let mut d = SceneDescription::default();
    let mut vertex = |p: Vec3, d: &mut SceneDescription| {
        d.positions
            .push(center + p * radius * rng.random_range(0.8..1.2));
        d.positions.len() as u32 - 1
    };
    let north = vertex(Vec3::Y, &mut d);
    let mut rows = Vec::new();
    for ring in 1..rings {
        let theta = std::f32::consts::PI * ring as f32 / rings as f32;
        let row: Vec<u32> = (0..segments)
            .map(|s| {
                let phi = std::f32::consts::TAU * s as f32 / segments as f32;
                let p = Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                );
                vertex(p, &mut d)
            })
            .collect();
        rows.push(row);
    }
    let south = vertex(Vec3::NEG_Y, &mut d);
    let mut tri = |a, b, c| {
        d.triangles.push(TriangleDesc {
            positions: [a, b, c],
            material: MaterialId(0),
        });
    };
    let n = segments as usize;
    for s in 0..n {
        tri(north, rows[0][(s + 1) % n], rows[0][s]);
        tri(
            south,
            rows[rows.len() - 1][s],
            rows[rows.len() - 1][(s + 1) % n],
        );
    }
    for pair in rows.windows(2) {
        for s in 0..n {
            let (a, b) = (pair[0][s], pair[0][(s + 1) % n]);
            let (c, e) = (pair[1][s], pair[1][(s + 1) % n]);
            tri(a, b, e);
            tri(a, e, c);
        }
    }
    d
}

#[test]
fn rays_from_inside_a_closed_mesh_always_hit_it() {
    let mut rng = Rng64::seed_from_u64(1);
    for trial in 0..8 {
        let center = Vec3::new(
            rng.random_range(-50.0..50.0),
            rng.random_range(-50.0..50.0),
            0.0,
        );
        let radius = rng.random_range(0.1..100.0);
        let rings = rng.random_range(3..40);
        let segments = rng.random_range(3..40);
        let scene = build(perturbed_sphere_mesh(
            &mut rng, center, radius, rings, segments,
        ));
        for _ in 0..20_000 {
            let origin = center + unit_vector(&mut rng) * radius * rng.random_range(0.0..0.5);
            let ray = Ray::new(origin, unit_vector(&mut rng));
            assert!(
                scene.intersect(&ray).is_some(),
                "trial {trial}: ray {ray:?} escaped a closed mesh ({rings}x{segments}, r = {radius})"
            );
        }
    }
}

#[test]
fn rays_spawned_from_a_triangle_hit_never_hit_it_again() {
    let mut rng = Rng64::seed_from_u64(2);
    for _ in 0..20_000 {
        let scale = 10f32.powf(rng.random_range(-2.0..3.0));
        let offset = unit_vector(&mut rng) * scale * rng.random_range(0.0..10.0);
        let vertices = [0; 3].map(|_| offset + unit_vector(&mut rng) * scale);
        let scene = build(SceneDescription {
            positions: vertices.to_vec(),
            triangles: vec![TriangleDesc {
                positions: [0, 1, 2],
                material: MaterialId(0),
            }],
            ..SceneDescription::default()
        });
        // Aim at a random point of the triangle from a random place.
        let (a, b) = (rng.random_range(0.0..1.0f32), rng.random_range(0.0..1.0f32));
        let (a, b) = if a + b > 1.0 {
            (1.0 - a, 1.0 - b)
        } else {
            (a, b)
        };
        let target =
            vertices[0] + (vertices[1] - vertices[0]) * a + (vertices[2] - vertices[0]) * b;
        let origin = target + unit_vector(&mut rng) * scale * 3.0;
        let Some(hit) = scene.intersect(&Ray::new(origin, target - origin)) else {
            continue;
        };
        let spawned = hit.spawn_ray(unit_vector(&mut rng));
        assert_eq!(scene.intersect(&spawned), None, "re-hit after {hit:?}");
    }
}

#[test]
fn rays_spawned_from_a_sphere_hit_leave_it_or_cross_it() {
    let mut rng = Rng64::seed_from_u64(3);
    for _ in 0..20_000 {
        let radius = 10f32.powf(rng.random_range(-2.0..3.0));
        let center = unit_vector(&mut rng) * radius * rng.random_range(0.0..10.0);
        let scene = build(SceneDescription {
            spheres: vec![SphereDesc {
                center,
                radius,
                material: MaterialId(0),
            }],
            ..SceneDescription::default()
        });
        let origin = center + unit_vector(&mut rng) * radius * rng.random_range(0.0..3.0);
        let Some(hit) = scene.intersect(&Ray::new(origin, unit_vector(&mut rng))) else {
            continue;
        };
        let dir = unit_vector(&mut rng);
        let outward = (hit.p - center).normalize();
        let spawned = hit.spawn_ray(dir);
        match scene.intersect(&spawned) {
            None => assert!(
                dir.dot(outward) >= -1e-3,
                "an inward ray must cross the sphere"
            ),
            Some(second) => {
                // Only an inward ray may hit, and then on the far side, not at the
                // point it left: the chord length is 2 r cos(angle to the inward normal).
                let chord = 2.0 * radius * (-dir.dot(outward));
                assert!(
                    dir.dot(outward) < 1e-3,
                    "outward ray re-hit the sphere at {}",
                    second.t
                );
                assert!(second.t >= 0.5 * chord, "t {} vs chord {chord}", second.t);
                assert!(((second.p - center).length() - radius).abs() <= 1e-3 * radius);
            }
        }
    }
}
