//! Pass 4: the faces' final shape, once every position is known. Passes 1-3 split every
//! polygon into the fan from its first corner (positions may be defined in any earlier
//! chunk, so a chunk cannot tell a concave polygon from a convex one); here the
//! polygons that are not convex in their plane are cut again by ear clipping
//! ([`polygon::triangulate`]), into the same number of triangles, in place. Then faces
//! without `vn` in a smoothing group (`s 1`, `s 2`...) get vertex normals averaged over
//! the faces of their group that share the vertex's position.
//!
//! Passes 1-3 note only what this pass needs: the faces of more than three corners,
//! and runs of triangles of faces without `vn`, with their group. A file of triangles
//! with `vn` (most meshes) notes nothing, and this pass costs nothing there.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use rayon::prelude::*;

use super::SceneDescription;
use crate::formats::polygon;
use crate::math::{Float, Vec3};

/// A smoothing group not set within the chunk: the one in force when the chunk starts,
/// known once the chunks before it are read.
pub(super) const INHERITED_GROUP: u32 = u32::MAX;

/// A face of more than three corners, as the fan of triangles passes 1-3 wrote for it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Polygon {
    /// Its first triangle (counted within the chunk until [`finish`]).
    pub(super) first: u32,
    /// Its corners: the fan has `corners - 2` triangles.
    pub(super) corners: u32,
}

/// Consecutive triangles of faces without `vn` (on every corner) in one smoothing group.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct SmoothRun {
    /// The first triangle (counted within the chunk until [`finish`]).
    pub(super) first: u32,
    pub(super) count: u32,
    /// The group, not 0 (no group), or [`INHERITED_GROUP`].
    pub(super) group: u32,
}

/// What a chunk's faces need of pass 4.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct Shaping {
    pub(super) polygons: Vec<Polygon>,
    pub(super) runs: Vec<SmoothRun>,
}

impl Shaping {
    /// Notes a face written as `triangles` triangles from the chunk's triangle `first`
    /// on: a polygon if more than one, a run if its corners lack `vn` and a smoothing
    /// group is (or may be) in force.
    #[inline(always)]
    pub(super) fn face(&mut self, first: usize, triangles: usize, all_normals: bool, group: u32) {
        if triangles > 1 {
            self.polygons.push(Polygon {
                first: first as u32,
                corners: triangles as u32 + 2,
            });
        }
        if all_normals || group == 0 {
            return;
        }
        if let Some(last) = self.runs.last_mut()
            && last.group == group
            && (last.first + last.count) as usize == first
        {
            last.count += triangles as u32;
            return;
        }
        self.runs.push(SmoothRun {
            first: first as u32,
            count: triangles as u32,
            group,
        });
    }
}

/// One chunk's notes, with where its triangles start in the file and the smoothing
/// group in force when it starts.
pub(super) struct ChunkFaces {
    pub(super) shaping: Shaping,
    pub(super) first_triangle: usize,
    pub(super) group_before: u32,
}

/// Pass 4 on the whole description.
pub(super) fn finish(scene: &mut SceneDescription, chunks: Vec<ChunkFaces>) {
    // Each chunk's polygons lie in its own triangles: the chunks are cut in parallel
    // (a file of quads has a polygon per face).
    if chunks.iter().any(|c| !c.shaping.polygons.is_empty()) {
        let mut parts = Vec::with_capacity(chunks.len());
        let mut rest = &mut scene.triangles[..];
        // Normal and texture coordinate indices, when kept, are cut with their
        // triangles.
        let mut rest_normals = &mut scene.triangle_normals[..];
        let mut rest_texcoords = &mut scene.triangle_texcoords[..];
        let mut at = 0;
        for (i, chunk) in chunks.iter().enumerate() {
            let end = chunks
                .get(i + 1)
                .map_or(at + rest.len(), |c| c.first_triangle);
            let (part, tail) = std::mem::take(&mut rest).split_at_mut(end - at);
            rest = tail;
            let normals = split_kept(&mut rest_normals, end - at);
            let texcoords = split_kept(&mut rest_texcoords, end - at);
            parts.push((part, normals, texcoords, &chunk.shaping.polygons));
            at = end;
        }
        let positions = &scene.positions;
        parts
            .into_par_iter()
            .for_each(|(triangles, mut normals, mut texcoords, polygons)| {
                for p in polygons {
                    let range = p.first as usize..p.first as usize + p.corners as usize - 2;
                    polygon::recut_fan(
                        positions,
                        &mut triangles[range.clone()],
                        normals.as_deref_mut().map(|n| &mut n[range.clone()]),
                        texcoords.as_deref_mut().map(|t| &mut t[range]),
                    );
                }
            });
    }
    let mut runs = Vec::new();
    for chunk in &chunks {
        let base = chunk.first_triangle;
        for run in &chunk.shaping.runs {
            let group = match run.group {
                INHERITED_GROUP => chunk.group_before,
                group => group,
            };
            if group != 0 {
                runs.push((base + run.first as usize, run.count as usize, group));
            }
        }
    }
    if !runs.is_empty() {
        smooth(scene, &runs);
    }
}

/// Gives the triangles of `runs` (first triangle, count, group) vertex normals: at each
/// corner, the mean of the unit normals of the group's triangles that have a corner at
/// the same position, weighted by their angle there (so that how a polygon was cut
/// into triangles does not matter, as it would with weights by area).
fn smooth(scene: &mut SceneDescription, runs: &[(usize, usize, u32)]) {
    // One normal per (group, position), positions told apart by value: exporters that
    // write each face's corners anew (as STL converters do) still join up.
    let mut by_value: HashMap<[u32; 3], u32, Fx> = HashMap::default();
    let mut slots: HashMap<(u32, u32), u32, Fx> = HashMap::default();
    let mut sums: Vec<Vec3> = Vec::new();
    let mut corners: Vec<[u32; 3]> = Vec::new();
    for &(first, count, group) in runs {
        for t in &scene.triangles[first..first + count] {
            let ids = t.positions.map(|i| {
                let p = scene.positions[i as usize];
                let key = p.to_array().map(|x| (x + 0.0).to_bits());
                let next = by_value.len() as u32;
                let value = *by_value.entry(key).or_insert(next);
                let next = sums.len() as u32;
                *slots.entry((group, value)).or_insert_with(|| {
                    sums.push(Vec3::ZERO);
                    next
                })
            });
            let [a, b, c] = t.positions.map(|i| scene.positions[i as usize]);
            if let Some(n) = (b - a).cross(c - a).try_normalize() {
                for (k, (p, q, r)) in [(a, b, c), (b, c, a), (c, a, b)].into_iter().enumerate() {
                    sums[ids[k] as usize] += n * angle(q - p, r - p);
                }
            }
            corners.push(ids);
        }
    }
    let base = scene.normals.len() as u32;
    scene.normals.extend(
        sums.iter()
            .map(|&n| n.try_normalize().unwrap_or(Vec3::ZERO)),
    );
    if scene.triangle_normals.is_empty() {
        scene.triangle_normals = vec![None; scene.triangles.len()];
    }
    let mut corners = corners.into_iter();
    for &(first, count, _) in runs {
        for normals in &mut scene.triangle_normals[first..first + count] {
            if let Some(ids) = corners.next() {
                *normals = Some(ids.map(|i| base + i));
            }
        }
    }
}

/// The first `len` elements of `rest` (taking them off it), or `None` if `rest` is
/// empty: an array in step with the triangles that the description does not keep.
fn split_kept<'a, T>(rest: &mut &'a mut [T], len: usize) -> Option<&'a mut [T]> {
    if rest.is_empty() {
        return None;
    }
    let (part, tail) = std::mem::take(rest).split_at_mut(len);
    *rest = tail;
    Some(part)
}

/// The angle between `u` and `v`, 0 if either is zero.
fn angle(u: Vec3, v: Vec3) -> Float {
    let (lu, lv) = (u.length(), v.length());
    if lu == 0.0 || lv == 0.0 {
        return 0.0;
    }
    (u.dot(v) / (lu * lv)).clamp(-1.0, 1.0).acos()
}

/// A fast hash for small keys of integers (FxHash's step): the maps here hold one entry
/// per vertex of a smoothed mesh, where SipHash's resistance to chosen keys buys
/// nothing.
#[derive(Default)]
struct FxHasher(u64);

type Fx = BuildHasherDefault<FxHasher>;

impl Hasher for FxHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u32(&mut self, n: u32) {
        self.write_u64(u64::from(n));
    }

    fn write_u64(&mut self, n: u64) {
        self.0 = (self.0.rotate_left(5) ^ n).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }

    fn write_usize(&mut self, n: usize) {
        self.write_u64(n as u64);
    }
}
