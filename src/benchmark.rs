//! Ray-throughput measurements on a built scene, as the `bench` command reports them:
//! closest-hit primary rays, any-hit shadow rays and closest-hit incoherent bounce
//! rays, without shading, ray by ray and (primary and shadow rays) as packets of a
//! 4x4 pixel tile, so that the numbers compare with ray-query libraries such as
//! Embree on the same rays (`--dump-rays` writes them for `bench/embree/`).

use std::time::Instant;

use rayon::prelude::*;

use crate::bvh::PACKET_SIZE;
use crate::camera::Camera;
use crate::math::{Float, Ray, Vec3};
use crate::options::RenderOptions;
use crate::sampler::PixelSampler;
use crate::scene::{Hit, Scene};

/// Side of the pixel tiles whose rays are traced as one packet.
const TILE: u32 = 4;
const _: () = assert!((TILE * TILE) as usize == PACKET_SIZE);

/// The rays of one benchmark: one primary ray per pixel centre; from every primary
/// hit one shadow ray to each light, and one bounce ray in a cosine-distributed
/// direction about the shading normal (as a path tracer's diffuse bounce). Primary
/// and shadow rays come tile by tile (4x4 pixels), as packets take them and as
/// `--dump-rays` writes them for Embree: single rays, packets and array queries on
/// both sides trace them in this one order (camera rays row by row instead ran
/// 1.03x-1.10x slower on the full dragon than the same rays tile by tile).
pub struct RayWorkload {
    /// The camera rays tile by tile (4x4 pixels, row by row within a tile).
    pub primary: Vec<Ray>,
    /// `(first, count)` ranges of `primary`, one per tile.
    pub primary_packets: Vec<(u32, u32)>,
    /// How many primary rays hit something.
    pub primary_hits: usize,
    /// The shadow rays with their distance to the light, by tile, then by light
    /// (each run one packet), the hits of a tile in the order of `primary`.
    pub shadow: Vec<(Ray, Float)>,
    /// `(first, count)` ranges of `shadow`, one per tile and light.
    pub shadow_packets: Vec<(u32, u32)>,
    /// One cosine-distributed bounce ray from every primary hit, row by row.
    pub incoherent: Vec<Ray>,
}

impl RayWorkload {
    /// Generates the rays for `options`' camera (tracing the primary rays once to find
    /// where the shadow rays start).
    pub fn new(scene: &Scene, options: &RenderOptions) -> RayWorkload {
        let camera = Camera::for_options(options);
        let (width, height) = (options.width, options.height);
        let by_row: Vec<Ray> = (0..height)
            .flat_map(|row| (0..width).map(move |column| camera.pixel_ray(column, row)))
            .collect();
        let hits = trace_closest(scene, &by_row);
        let primary_hits = hits.iter().flatten().count();

        let mut primary = Vec::with_capacity(by_row.len());
        let mut primary_packets = Vec::new();
        let mut shadow = Vec::new();
        let mut shadow_packets = Vec::new();
        for top in (0..height).step_by(TILE as usize) {
            for left in (0..width).step_by(TILE as usize) {
                let pixels: Vec<usize> = (top..(top + TILE).min(height))
                    .flat_map(|row| {
                        (left..(left + TILE).min(width)).map(move |c| (row * width + c) as usize)
                    })
                    .collect();
                primary_packets.push((primary.len() as u32, pixels.len() as u32));
                primary.extend(pixels.iter().map(|&p| by_row[p]));
                for light in &scene.lights {
                    let first = shadow.len() as u32;
                    shadow.extend(
                        pixels
                            .iter()
                            .filter_map(|&p| hits[p].as_ref())
                            .map(|hit| hit.spawn_ray_to(light.position)),
                    );
                    let count = shadow.len() as u32 - first;
                    if count > 0 {
                        shadow_packets.push((first, count));
                    }
                }
            }
        }

        // Two sample dimensions per pixel, hashed as the renderer's sampler does.
        let sampler = PixelSampler::new(1, 2);
        let incoherent = hits
            .iter()
            .enumerate()
            .filter_map(|(pixel, hit)| {
                let hit = hit.as_ref()?;
                let u = sampler.sample(pixel as u64, 0).next_2d();
                Some(hit.spawn_ray(cosine_about(hit.ns, u.x, u.y)))
            })
            .collect();
        RayWorkload {
            primary,
            primary_packets,
            primary_hits,
            shadow,
            shadow_packets,
            incoherent,
        }
    }

    /// Writes the scene's triangles and the rays for the Embree benchmark
    /// (`bench/embree/embree_bench.c`, which documents the layout): little-endian
    /// counts (`u32`) and `f32` arrays.
    ///
    /// # Errors
    /// The file cannot be written.
    pub fn dump(
        &self,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        path: &std::path::Path,
    ) -> std::io::Result<()> {
        use std::io::Write;
        let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
        let put_u32 =
            |out: &mut std::io::BufWriter<std::fs::File>, v: u32| out.write_all(&v.to_le_bytes());
        let put_f32 =
            |out: &mut std::io::BufWriter<std::fs::File>, v: f32| out.write_all(&v.to_le_bytes());
        out.write_all(b"RTBENCH1")?;
        put_u32(&mut out, positions.len() as u32)?;
        for p in positions {
            for v in p.to_array() {
                put_f32(&mut out, v)?;
            }
        }
        put_u32(&mut out, triangles.len() as u32)?;
        for t in triangles {
            for &v in t {
                put_u32(&mut out, v)?;
            }
        }
        let put_ray = |out: &mut std::io::BufWriter<std::fs::File>, r: &Ray, t_max: f32| {
            for v in r.origin.to_array().into_iter().chain(r.dir.to_array()) {
                put_f32(out, v)?;
            }
            put_f32(out, t_max)
        };
        // Primary rays and their packets; shadow rays and their packets; bounces.
        put_u32(&mut out, self.primary.len() as u32)?;
        for r in &self.primary {
            put_ray(&mut out, r, Float::INFINITY)?;
        }
        put_u32(&mut out, self.primary_packets.len() as u32)?;
        for &(first, count) in &self.primary_packets {
            put_u32(&mut out, first)?;
            put_u32(&mut out, count)?;
        }
        put_u32(&mut out, self.shadow.len() as u32)?;
        for (r, t_max) in &self.shadow {
            put_ray(&mut out, r, *t_max)?;
        }
        put_u32(&mut out, self.shadow_packets.len() as u32)?;
        for &(first, count) in &self.shadow_packets {
            put_u32(&mut out, first)?;
            put_u32(&mut out, count)?;
        }
        put_u32(&mut out, self.incoherent.len() as u32)?;
        for r in &self.incoherent {
            put_ray(&mut out, r, Float::INFINITY)?;
        }
        out.flush()
    }
}

/// A cosine-distributed unit direction about the unit vector `axis` from two uniform
/// numbers in `[0, 1)`.
fn cosine_about(axis: Vec3, u1: Float, u2: Float) -> Vec3 {
    let r = u1.sqrt();
    let phi = 2.0 * std::f32::consts::PI * u2;
    let local = Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt());
    // Any orthonormal frame will do (Duff et al. 2017).
    let sign = 1.0_f32.copysign(axis.z);
    let a = -1.0 / (sign + axis.z);
    let b = axis.x * axis.y * a;
    let tangent = Vec3::new(1.0 + sign * axis.x * axis.x * a, sign * b, -sign * axis.x);
    let bitangent = Vec3::new(b, sign + axis.y * axis.y * a, -axis.y);
    (local.x * tangent + local.y * bitangent + local.z * axis).normalize()
}

/// Closest hits of `rays`, in parallel.
pub fn trace_closest(scene: &Scene, rays: &[Ray]) -> Vec<Option<Hit>> {
    let mut hits = Vec::with_capacity(rays.len());
    rays.par_iter()
        .map(|ray| scene.intersect(ray))
        .collect_into_vec(&mut hits);
    hits
}

/// The primitive each of `rays` hits first (`u32::MAX` for a miss), in parallel:
/// closest-hit queries without shading, as a ray-query library such as Embree
/// answers them (its Python binding returns an array of primitive ids).
pub fn trace_closest_primitives(scene: &Scene, rays: &[Ray]) -> Vec<u32> {
    let mut ids = Vec::with_capacity(rays.len());
    rays.par_iter()
        .map(|ray| {
            scene
                .intersect_primitive(ray)
                .map_or(u32::MAX, |(prim, _)| prim)
        })
        .collect_into_vec(&mut ids);
    ids
}

/// [`trace_closest_primitives`] through the array query
/// ([`Scene::intersect_primitives`], which walks several rays at a time in scenes
/// larger than the last-level cache), in parallel chunks.
pub fn trace_closest_primitives_stream(scene: &Scene, rays: &[Ray]) -> Vec<u32> {
    const CHUNK: usize = 256;
    let mut ids = vec![u32::MAX; rays.len()];
    ids.par_chunks_mut(CHUNK)
        .zip(rays.par_chunks(CHUNK))
        .for_each(|(ids, rays)| {
            let mut hits = [None; CHUNK];
            let hits = &mut hits[..rays.len()];
            scene.intersect_primitives(rays, hits);
            for (id, hit) in ids.iter_mut().zip(hits) {
                *id = hit.map_or(u32::MAX, |(prim, _)| prim);
            }
        });
    ids
}

/// [`trace_closest_primitives`] of `rays` in packets: one packet per `(first, count)`
/// range of `packets`, in parallel; the ids in the order of `rays`.
pub fn trace_closest_primitives_packets(
    scene: &Scene,
    rays: &[Ray],
    packets: &[(u32, u32)],
) -> Vec<u32> {
    let mut ids = vec![u32::MAX; rays.len()];
    let mut chunks = Vec::with_capacity(packets.len());
    let mut rest = ids.as_mut_slice();
    for &(_, count) in packets {
        let (chunk, tail) = rest.split_at_mut(count as usize);
        chunks.push(chunk);
        rest = tail;
    }
    chunks
        .into_par_iter()
        .zip(packets)
        .for_each(|(ids, &(first, count))| {
            let rays = &rays[first as usize..(first + count) as usize];
            scene.intersect_primitive_packet(rays, ids);
        });
    ids
}

/// [`count_occluded`] in packets: one per `(first, count)` range of `packets`.
pub fn count_occluded_packets(
    scene: &Scene,
    rays: &[(Ray, Float)],
    packets: &[(u32, u32)],
) -> usize {
    packets
        .par_iter()
        .map(|&(first, count)| {
            let group = &rays[first as usize..(first + count) as usize];
            let mut packet_rays = [Ray::new(Vec3::ZERO, Vec3::Z); PACKET_SIZE];
            let mut t_max = [0.0; PACKET_SIZE];
            for (k, (ray, t)) in group.iter().enumerate() {
                packet_rays[k] = *ray;
                t_max[k] = *t;
            }
            let n = group.len();
            let all = (1u32 << n) - 1;
            scene
                .occluded_packet(&packet_rays[..n], &t_max[..n], all)
                .count_ones() as usize
        })
        .sum()
}

/// How many of `rays` are blocked before their distance, in parallel.
pub fn count_occluded(scene: &Scene, rays: &[(Ray, Float)]) -> usize {
    rays.par_iter()
        .filter(|(ray, t_max)| scene.occluded(ray, *t_max))
        .count()
}

/// [`count_occluded`] through the array query ([`Scene::occluded_rays`], which walks
/// several rays at a time in scenes larger than the last-level cache), in parallel
/// chunks: `rays[i]` within its reach `t_max[i]`.
pub fn count_occluded_stream(scene: &Scene, rays: &[Ray], t_max: &[Float]) -> usize {
    const CHUNK: usize = 256;
    rays.par_chunks(CHUNK)
        .zip(t_max.par_chunks(CHUNK))
        .map(|(rays, t_max)| {
            let mut blocked = [false; CHUNK];
            let blocked = &mut blocked[..rays.len()];
            scene.occluded_rays(rays, t_max, blocked);
            blocked.iter().filter(|&&b| b).count()
        })
        .sum()
}

/// Runs `f` `repeat` times (at least once) and returns its last result and the median
/// wall time in seconds.
pub fn median_time<T>(repeat: usize, mut f: impl FnMut() -> T) -> (T, f64) {
    let (result, times) = median_times_with(repeat, || (), |()| f());
    (result, times.wall)
}

/// [`median_time`] of `f` on a fresh `input()` each time, made before the clock
/// starts; the previous result is dropped before it starts too, so that only `f` is
/// timed.
pub fn median_time_with<I, T>(
    repeat: usize,
    input: impl FnMut() -> I,
    f: impl FnMut(I) -> T,
) -> (T, f64) {
    let (result, times) = median_times_with(repeat, input, f);
    (result, times.wall)
}

/// Median wall time and median CPU time (user and system, all threads of the process)
/// of some runs, in seconds. On a shared, loaded machine the CPU time moves less than
/// the wall time: it does not count the time the threads waited for a core.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Times {
    /// Median wall time.
    pub wall: f64,
    /// Median CPU time of the process over the run.
    pub cpu: f64,
}

/// [`median_time`] with the median CPU time too.
pub fn median_times<T>(repeat: usize, mut f: impl FnMut() -> T) -> (T, Times) {
    median_times_with(repeat, || (), |()| f())
}

/// [`median_time_with`] with the median CPU time too.
pub fn median_times_with<I, T>(
    repeat: usize,
    mut input: impl FnMut() -> I,
    mut f: impl FnMut(I) -> T,
) -> (T, Times) {
    let mut wall = Vec::with_capacity(repeat.max(1));
    let mut cpu = Vec::with_capacity(repeat.max(1));
    let mut result = None;
    for _ in 0..repeat.max(1) {
        drop(result.take());
        let input = input();
        let (start, start_cpu) = (Instant::now(), process_cpu_seconds());
        result = Some(f(input));
        wall.push(start.elapsed().as_secs_f64());
        cpu.push(process_cpu_seconds() - start_cpu);
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let result = result.expect("ran at least once");
    (
        result,
        Times {
            wall: median(wall),
            cpu: median(cpu),
        },
    )
}

/// User and system CPU seconds of the whole process so far (0 where unknown).
fn process_cpu_seconds() -> f64 {
    let mut usage = std::mem::MaybeUninit::<libc::rusage>::zeroed();
    // SAFETY: `getrusage` fills the struct it is given; RUSAGE_SELF is always valid.
    let usage = unsafe {
        if libc::getrusage(libc::RUSAGE_SELF, usage.as_mut_ptr()) != 0 {
            return 0.0;
        }
        usage.assume_init()
    };
    let seconds = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    seconds(usage.ru_utime) + seconds(usage.ru_stime)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Primary and shadow rays come tile by tile, each packet one 4x4 tile's rays
    /// (shadow rays: one tile's towards one light), ragged tiles at the right and
    /// bottom edges included: the one order single rays, packets and Embree trace.
    #[test]
    fn rays_come_tile_by_tile_in_their_packets() {
        use crate::description::{SceneDescription, TriangleDesc};
        use crate::material::{Light, MaterialId};
        let light = |x: Float| Light::point(Vec3::new(x, 3.0, 0.0), Vec3::ONE);
        let description = SceneDescription {
            positions: vec![
                Vec3::new(-9.0, -1.0, -9.0),
                Vec3::new(9.0, -1.0, -9.0),
                Vec3::new(0.0, -1.0, 9.0),
            ],
            triangles: vec![TriangleDesc {
                positions: [0, 2, 1],
                material: MaterialId(0),
            }],
            lights: vec![light(-1.0), light(1.0)],
            ..SceneDescription::default()
        };
        let scene = Scene::build(description, &crate::BvhParams::default());
        let options = RenderOptions {
            width: 10,
            height: 6,
            ..RenderOptions::default()
        };
        let workload = RayWorkload::new(&scene, &options);
        let camera = Camera::for_options(&options);
        let mut tile_pixels = Vec::new();
        for top in (0..6).step_by(4) {
            for left in (0..10).step_by(4) {
                let pixels: Vec<(u32, u32)> = (top..(top + 4).min(6))
                    .flat_map(|row| (left..(left + 4).min(10)).map(move |c| (c, row)))
                    .collect();
                tile_pixels.push(pixels);
            }
        }
        assert_eq!(workload.primary_packets.len(), tile_pixels.len());
        let mut next = 0;
        for (&(first, count), pixels) in workload.primary_packets.iter().zip(&tile_pixels) {
            assert_eq!((first, count as usize), (next, pixels.len()));
            for (ray, &(column, row)) in workload.primary[first as usize..].iter().zip(pixels) {
                assert_eq!(ray.dir, camera.pixel_ray(column, row).dir);
            }
            next += count;
        }
        assert_eq!(next as usize, workload.primary.len());
        assert!(workload.primary_hits > 0 && workload.primary_hits < 60);
        // Shadow rays: consecutive runs, each towards one light, the lights in turn.
        let mut next = 0;
        for (k, &(first, count)) in workload.shadow_packets.iter().enumerate() {
            assert_eq!(first, next);
            let target = scene.lights[k % 2].position;
            for (ray, reach) in &workload.shadow[first as usize..(first + count) as usize] {
                let end = ray.origin + ray.dir * *reach;
                assert!(
                    (end - target).length() < 1e-3,
                    "{end} is not light {}",
                    k % 2
                );
            }
            next += count;
        }
        assert_eq!(next as usize, 2 * workload.primary_hits);
    }

    /// Bounce directions are unit vectors on the side of the axis, cosine-distributed:
    /// the mean cosine of a cosine-weighted hemisphere is 2/3.
    #[test]
    fn bounces_are_cosine_distributed_about_the_axis() {
        let sampler = PixelSampler::new(1, 2);
        for axis in [Vec3::Z, -Vec3::Z, Vec3::new(0.3, -0.8, 0.52).normalize()] {
            let n = 20_000;
            let mut sum = 0.0;
            for i in 0..n {
                let u = sampler.sample(i, 0).next_2d();
                let dir = cosine_about(axis, u.x, u.y);
                assert!((dir.length() - 1.0).abs() < 1e-5, "{dir}");
                let cos = dir.dot(axis);
                assert!(cos >= -1e-6, "{dir} leaves {axis}'s side");
                sum += cos as f64;
            }
            let mean = sum / n as f64;
            assert!(
                (mean - 2.0 / 3.0).abs() < 0.01,
                "mean cosine {mean} about {axis}"
            );
        }
    }
}
