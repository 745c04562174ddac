//! Rays given by Python (`Scene.intersect`, `Scene.occluded`): `(n, 3)` arrays of
//! origins and directions checked and made into rays a chunk at a time on every
//! core, traced through the library's array queries ([`Scene::intersect_primitives`],
//! [`Scene::occluded_rays`]), and their answers written once each into the arrays
//! handed back.

use numpy::ndarray::{ArrayViewD, CowArray, Ix2};
use numpy::{AllowTypeChange, PyArrayLikeDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rayon::prelude::*;
use raytracer::Scene;
use raytracer::math::{Float, Ray, Vec3};
use raytracer::shapes::PrimHit;

use crate::test_gate;

/// `value` (an array, or anything numpy makes one of) as `float32` numbers.
pub(crate) fn numbers_of<'py>(
    value: &Bound<'py, PyAny>,
    name: &str,
    expected: &str,
) -> PyResult<PyArrayLikeDyn<'py, f32, AllowTypeChange>> {
    value
        .extract()
        .map_err(|e: PyErr| PyValueError::new_err(format!("{name} must be {expected}: {e}")))
}

/// What [`numbers_of`] expects of a ray argument.
pub(crate) const RAY_ROWS: &str = "an (n, 3) array of numbers";

/// The rows of an `(n, 3)` array as `3 n` numbers in row order, without a copy when
/// the array is contiguous.
pub(crate) fn rows_of<'a>(
    array: ArrayViewD<'a, f32>,
    name: &str,
) -> PyResult<CowArray<'a, f32, Ix2>> {
    if array.ndim() != 2 || array.shape()[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "{name} must have the shape (n, 3), one row of three numbers per ray, not {}",
            shape_text(array.shape())
        )));
    }
    let array = array.into_dimensionality::<Ix2>().expect("two dimensions");
    Ok(if array.is_standard_layout() {
        CowArray::from(array)
    } else {
        CowArray::from(array.as_standard_layout().into_owned())
    })
}

/// A shape as numpy writes it: `()`, `(3,)`, `(2, 4)`.
pub(crate) fn shape_text(shape: &[usize]) -> String {
    match shape {
        [length] => format!("({length},)"),
        lengths => format!(
            "({})",
            lengths
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// The rows of `origins` and `directions`, one of each per ray.
pub(crate) fn ray_rows<'a>(
    origins: &'a PyArrayLikeDyn<'_, f32, AllowTypeChange>,
    directions: &'a PyArrayLikeDyn<'_, f32, AllowTypeChange>,
) -> PyResult<(CowArray<'a, f32, Ix2>, CowArray<'a, f32, Ix2>)> {
    let origins = rows_of(origins.as_array(), "origins")?;
    let directions = rows_of(directions.as_array(), "directions")?;
    if origins.nrows() != directions.nrows() {
        return Err(PyValueError::new_err(format!(
            "{} origins but {} directions: give one of each per ray",
            origins.nrows(),
            directions.nrows()
        )));
    }
    Ok((origins, directions))
}

/// Why ray `row` cannot be traced.
pub(crate) struct BadRay {
    row: usize,
    origin: Vec3,
    dir: Vec3,
}

impl From<BadRay> for PyErr {
    fn from(BadRay { row, origin, dir }: BadRay) -> PyErr {
        PyValueError::new_err(if origin.is_finite() && dir.is_finite() {
            format!("ray {row}: the direction {dir} is zero")
        } else {
            format!("ray {row}: origin {origin} and direction {dir} must be finite")
        })
    }
}

/// The ray of row `row`: finite numbers and a direction that is not zero, made unit
/// length.
#[inline]
fn ray_at(row: usize, origin: &[f32], dir: &[f32]) -> Result<Ray, BadRay> {
    let origin = Vec3::from_slice(origin);
    let dir = Vec3::from_slice(dir);
    let length_squared = dir.length_squared();
    if origin.is_finite() && (f32::MIN_POSITIVE..f32::INFINITY).contains(&length_squared) {
        // As `Vec3::normalize`, without its checks: the squared length is normal.
        let dir = dir * length_squared.sqrt().recip();
        return Ok(Ray { origin, dir });
    }
    // Directions whose squared length underflows or overflows, scaled first; zero,
    // infinite and NaN ones end up not unit length.
    let unit = (dir / dir.abs().max_element()).normalize_or_zero();
    if origin.is_finite() && unit.is_normalized() {
        Ok(Ray { origin, dir: unit })
    } else {
        Err(BadRay { row, origin, dir })
    }
}

/// The closest hits of `Scene.intersect`, by coordinate.
pub(crate) struct ClosestHits {
    pub(crate) t: Vec<f32>,
    pub(crate) primitive: Vec<i64>,
    pub(crate) u: Vec<f32>,
    pub(crate) v: Vec<f32>,
}

/// Rays per task: enough for the array query to keep several in flight.
const RAY_CHUNK: usize = 256;

/// The rays `first..first + rays.len()` of `origins` and `directions` (three numbers
/// per ray, from `first` on), into `rays`, or the first that cannot be traced.
#[inline]
fn make_rays(
    first: usize,
    origins: &[f32],
    directions: &[f32],
    rays: &mut [Ray],
) -> Result<(), BadRay> {
    for (i, ray) in rays.iter_mut().enumerate() {
        let at = 3 * i..3 * i + 3;
        *ray = ray_at(first + i, &origins[at.clone()], &directions[at])?;
    }
    Ok(())
}

/// A chunk of rays on the stack, for [`make_rays`].
const NO_RAYS: [Ray; RAY_CHUNK] = [Ray {
    origin: Vec3::ZERO,
    dir: Vec3::Z,
}; RAY_CHUNK];

/// Whether the first bad ray of `bad` (the chunks' first, in no order) exists: its
/// error. Every chunk without one wrote all its outputs.
fn first_bad(bad: impl ParallelIterator<Item = BadRay>) -> Result<(), BadRay> {
    bad.min_by_key(|bad| bad.row).map_or(Ok(()), Err)
}

/// The closest hit of every ray (`origins` and `directions` hold three numbers per
/// ray), on all cores, or the first ray that cannot be traced. Call detached from the
/// interpreter.
pub(crate) fn closest_hits(
    scene: &Scene,
    origins: &[f32],
    directions: &[f32],
) -> Result<ClosestHits, BadRay> {
    test_gate("RAYTRACER_TEST_GATE_INTERSECT");
    // The rays are made, checked and traced a chunk at a time, and each output is
    // written once, by the thread that traced its rays: on the dragon's 786k camera
    // rays, a whole array of rays and filled outputs made first took as long as the
    // tracing.
    let n = origins.len() / 3;
    let mut t = Vec::with_capacity(n);
    let mut primitive = Vec::with_capacity(n);
    let mut u = Vec::with_capacity(n);
    let mut v = Vec::with_capacity(n);
    first_bad(
        origins
            .par_chunks(3 * RAY_CHUNK)
            .zip(directions.par_chunks(3 * RAY_CHUNK))
            .zip(t.spare_capacity_mut()[..n].par_chunks_mut(RAY_CHUNK))
            .zip(primitive.spare_capacity_mut()[..n].par_chunks_mut(RAY_CHUNK))
            .zip(
                u.spare_capacity_mut()[..n]
                    .par_chunks_mut(RAY_CHUNK)
                    .zip(v.spare_capacity_mut()[..n].par_chunks_mut(RAY_CHUNK)),
            )
            .enumerate()
            .filter_map(
                |(chunk, ((((origins, directions), t), primitive), (u, v)))| {
                    let mut rays = NO_RAYS;
                    let rays = &mut rays[..t.len()];
                    if let Err(bad) = make_rays(chunk * RAY_CHUNK, origins, directions, rays) {
                        return Some(bad);
                    }
                    let mut found = [None; RAY_CHUNK];
                    let found = &mut found[..rays.len()];
                    scene.intersect_primitives(rays, found);
                    for (i, hit) in found.iter().enumerate() {
                        let (prim, hit) = match *hit {
                            Some((prim, hit)) => (scene.source_index(prim) as i64, hit),
                            None => (
                                -1,
                                PrimHit {
                                    t: Float::INFINITY,
                                    u: 0.0,
                                    v: 0.0,
                                },
                            ),
                        };
                        t[i].write(hit.t);
                        primitive[i].write(prim);
                        u[i].write(hit.u);
                        v[i].write(hit.v);
                    }
                    None
                },
            ),
    )?;
    // SAFETY: every chunk without a bad ray wrote all its elements, and there was none.
    unsafe {
        t.set_len(n);
        primitive.set_len(n);
        u.set_len(n);
        v.set_len(n);
    }
    Ok(ClosestHits { t, primitive, u, v })
}

/// Whether anything blocks each ray before its reach (`reach(row)`), on all cores, or
/// the first ray that cannot be traced. Call detached from the interpreter.
pub(crate) fn blocked_rays(
    scene: &Scene,
    origins: &[f32],
    directions: &[f32],
    reach: impl Fn(usize) -> Float + Sync,
) -> Result<Vec<bool>, BadRay> {
    test_gate("RAYTRACER_TEST_GATE_INTERSECT");
    let n = origins.len() / 3;
    let mut blocked = Vec::with_capacity(n);
    first_bad(
        origins
            .par_chunks(3 * RAY_CHUNK)
            .zip(directions.par_chunks(3 * RAY_CHUNK))
            .zip(blocked.spare_capacity_mut()[..n].par_chunks_mut(RAY_CHUNK))
            .enumerate()
            .filter_map(|(chunk, ((origins, directions), blocked))| {
                let first = chunk * RAY_CHUNK;
                let mut rays = NO_RAYS;
                let rays = &mut rays[..blocked.len()];
                if let Err(bad) = make_rays(first, origins, directions, rays) {
                    return Some(bad);
                }
                let mut reaches = [0.0; RAY_CHUNK];
                let reaches = &mut reaches[..rays.len()];
                for (i, t_max) in reaches.iter_mut().enumerate() {
                    *t_max = reach(first + i);
                }
                let mut found = [false; RAY_CHUNK];
                let found = &mut found[..rays.len()];
                scene.occluded_rays(rays, reaches, found);
                for (blocked, &found) in blocked.iter_mut().zip(found.iter()) {
                    blocked.write(found);
                }
                None
            }),
    )?;
    // SAFETY: every chunk without a bad ray wrote all its elements, and there was none.
    unsafe { blocked.set_len(n) };
    Ok(blocked)
}

/// How far `Scene.occluded` looks along each ray: its `t_max` argument.
pub(crate) enum Reach {
    /// One distance for every ray (no limit when `t_max` is `None`).
    Every(Float),
    /// One distance per ray.
    Each(Vec<Float>),
}

impl Reach {
    /// `t_max` for `n` rays: `None`, one number, or one per ray, none NaN.
    pub(crate) fn of(t_max: Option<&Bound<'_, PyAny>>, n: usize) -> PyResult<Reach> {
        let Some(t_max) = t_max else {
            return Ok(Reach::Every(Float::INFINITY));
        };
        let t_max = numbers_of(t_max, "t_max", "a number or an array of numbers")?;
        let t_max = t_max.as_array();
        if !(t_max.ndim() == 0 || t_max.shape() == [n]) {
            return Err(PyValueError::new_err(format!(
                "t_max must be one number or one per ray ({n}), not {}",
                shape_text(t_max.shape())
            )));
        }
        if let Some(row) = t_max.iter().position(|t| t.is_nan()) {
            return Err(PyValueError::new_err(if t_max.ndim() == 0 {
                "t_max is NaN".to_string()
            } else {
                format!("ray {row}: t_max is NaN")
            }));
        }
        Ok(match t_max.ndim() {
            0 => Reach::Every(t_max.iter().copied().next().unwrap_or(Float::INFINITY)),
            _ => Reach::Each(t_max.iter().copied().collect()),
        })
    }

    /// The reach of ray `row`.
    #[inline]
    pub(crate) fn at(&self, row: usize) -> Float {
        match self {
            Reach::Every(t_max) => *t_max,
            Reach::Each(t_max) => t_max[row],
        }
    }
}
