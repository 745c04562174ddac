//! Combining meshes into one description: index offsets, material ids and placement.

use glam::{Affine3A, DMat3, Mat3};
use rayon::prelude::*;

use super::SceneDescription;
use super::error::ParseErrorKind;
use crate::description::InstanceDesc;
use crate::material::{LightKind, MaterialId};
use crate::math::{Float, Vec3};

/// Elements per task of the passes over a mesh's arrays in
/// [`SceneDescription::append`]: small meshes stay on the calling thread.
const PARALLEL_RUN: usize = 1 << 14;

/// Where a mesh goes in the world: `world_from_object = translate * rotate * scale`,
/// that is scale first, then rotate about x, then y, then z (right-handed,
/// counter-clockwise looking down the axis), then translate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// The linear part, `rotate * scale`.
    linear: Mat3,
    /// The inverse transpose of `linear`: it keeps normals perpendicular to their
    /// surface under non-uniform scale, where `linear` itself would tilt them.
    normal_from_object: Mat3,
    translation: Vec3,
    scale: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Transform::IDENTITY
    }
}

impl Transform {
    /// The transform that leaves everything in place.
    pub const IDENTITY: Transform = Transform {
        linear: Mat3::IDENTITY,
        normal_from_object: Mat3::IDENTITY,
        translation: Vec3::ZERO,
        scale: Vec3::ONE,
    };

    /// Scale per axis, then rotate by `rotate_degrees` about x, y and z in turn, then
    /// translate. Every scale component must be non-zero (a flattened mesh has no
    /// normals); the TOML reader checks this.
    pub fn new(scale: Vec3, rotate_degrees: Vec3, translate: Vec3) -> Transform {
        debug_assert!(scale.cmpne(Vec3::ZERO).all(), "zero scale");
        let r = rotate_degrees * (std::f32::consts::PI / 180.0);
        let rotation =
            Mat3::from_rotation_z(r.z) * Mat3::from_rotation_y(r.y) * Mat3::from_rotation_x(r.x);
        let linear = rotation * Mat3::from_diagonal(scale);
        Transform {
            linear,
            normal_from_object: linear.inverse().transpose(),
            translation: translate,
            scale,
        }
    }

    /// A point moved into the world.
    #[inline]
    pub fn point(&self, p: Vec3) -> Vec3 {
        self.linear * p + self.translation
    }

    /// A normal moved into the world (not normalized).
    #[inline]
    pub fn normal(&self, n: Vec3) -> Vec3 {
        self.normal_from_object * n
    }

    /// A vertex tangent ([`SceneDescription::tangents`]) moved into the world: its
    /// direction, a direction in the surface, by the linear part (not normalized),
    /// and its bitangent sign turned by a mirroring transform (`cross(N n, M t)` then
    /// runs against `M b`); zero (none) stays zero.
    #[inline]
    pub fn tangent(&self, t: glam::Vec4) -> glam::Vec4 {
        let sign = if self.linear.determinant() < 0.0 {
            -1.0
        } else {
            1.0
        };
        (self.linear * t.truncate()).extend(t.w * sign)
    }

    /// An instance's placement as a transform for [`SceneDescription::append`] (of
    /// meshes without spheres: it has no uniform scale).
    pub fn from_affine(a: &Affine3A) -> Transform {
        let linear = Mat3::from(a.matrix3);
        Transform {
            linear,
            normal_from_object: linear.inverse().transpose(),
            translation: a.translation.into(),
            scale: Vec3::new(1.0, 2.0, 3.0),
        }
    }

    /// The same placement as an affine map (world from object), for instances.
    pub fn to_affine(&self) -> Affine3A {
        Affine3A::from_mat3_translation(self.linear, self.translation)
    }

    /// The factor by which lengths grow in every direction, when the scale has the
    /// same magnitude on all axes (so spheres stay spheres).
    pub fn uniform_scale(&self) -> Option<Float> {
        let s = self.scale.abs();
        (s.x == s.y && s.y == s.z).then_some(s.x)
    }
}

impl SceneDescription {
    /// Adds `mesh` to this description: its points (vertices, sphere centres and
    /// lights) moved by `transform`, its indices and material ids shifted to follow
    /// what is already here. With `material`, every shape of `mesh` gets that material
    /// and the mesh's own materials are dropped; otherwise they are appended.
    ///
    /// # Errors
    /// More vertices or triangles in all than 32-bit indices can address. If `mesh`
    /// has spheres, `transform` must have a [`Transform::uniform_scale`]; otherwise
    /// this returns an error, too.
    pub fn append(
        &mut self,
        mesh: SceneDescription,
        transform: &Transform,
        material: Option<MaterialId>,
    ) -> Result<(), ParseErrorKind> {
        // A mesh file with instances of its own (a glTF file with shared meshes) is
        // placed as its copies.
        let mut mesh = mesh;
        if !mesh.instances.is_empty() {
            mesh.flatten_instances()?;
        }
        let radius_scale = match transform.uniform_scale() {
            Some(s) => s,
            None if mesh.spheres.is_empty() => 1.0,
            None => return Err(ParseErrorKind::NonUniformSphereScale),
        };
        let fits = |a: usize, b: usize| a.checked_add(b).is_some_and(|n| n <= u32::MAX as usize);
        if !fits(self.positions.len(), mesh.positions.len())
            || !fits(self.normals.len(), mesh.normals.len())
            || !fits(self.texcoords.len(), mesh.texcoords.len())
        {
            return Err(ParseErrorKind::TooMany("vertices"));
        }
        if !fits(self.triangles.len(), mesh.triangles.len()) {
            return Err(ParseErrorKind::TooMany("triangles"));
        }
        let position_offset = self.positions.len() as u32;
        let normal_offset = self.normals.len() as u32;
        let texcoord_offset = self.texcoords.len() as u32;
        let material_offset = self.materials.len() as u32;
        let material_of = |id: MaterialId| material.unwrap_or(MaterialId(id.0 + material_offset));

        // Work in place on the mesh's arrays and then move them over: a large first
        // mesh (the usual case) is never copied. On all threads: one thread took 5 ms
        // of the dragon's 48 ms load for these passes (the same arithmetic either way,
        // so the same bits).
        mesh.positions
            .par_iter_mut()
            .with_min_len(PARALLEL_RUN)
            .for_each(|p| *p = transform.point(*p));
        mesh.normals
            .par_iter_mut()
            .with_min_len(PARALLEL_RUN)
            .for_each(|n| *n = transform.normal(*n));
        mesh.tangents
            .par_iter_mut()
            .with_min_len(PARALLEL_RUN)
            .for_each(|t| *t = transform.tangent(*t));
        mesh.triangles
            .par_iter_mut()
            .with_min_len(PARALLEL_RUN)
            .for_each(|t| {
                t.positions = t.positions.map(|i| i + position_offset);
                t.material = material_of(t.material);
            });
        for s in &mut mesh.spheres {
            s.center = transform.point(s.center);
            s.radius *= radius_scale;
            s.material = material_of(s.material);
        }
        for l in &mut mesh.lights {
            l.position = transform.point(l.position);
            if let LightKind::Spot { direction, .. } | LightKind::Directional { direction } =
                &mut l.kind
            {
                // Turned with the mesh; the scale is non-zero on every axis, so the
                // direction stays non-zero.
                *direction = (transform.linear * *direction).normalize();
            }
        }
        for (indices, offset) in [
            (&mut mesh.triangle_texcoords, texcoord_offset),
            (&mut mesh.triangle_normals, normal_offset),
        ] {
            if offset != 0 {
                indices
                    .par_iter_mut()
                    .with_min_len(PARALLEL_RUN)
                    .flatten()
                    .for_each(|t| *t = t.map(|i| i + offset));
            }
        }
        // Normal and texture coordinate indices stay in step with the triangles: if
        // only one side has them, the other's triangles have none.
        for (ours, theirs) in [
            (&mut self.triangle_texcoords, mesh.triangle_texcoords),
            (&mut self.triangle_normals, mesh.triangle_normals),
        ] {
            if !theirs.is_empty() || !ours.is_empty() {
                let mut theirs = theirs;
                ours.resize(self.triangles.len(), None);
                theirs.resize(mesh.triangles.len(), None);
                append(ours, theirs);
            }
        }
        // The mesh's objects follow the shapes already here.
        let (triangles_before, spheres_before) =
            (self.triangles.len() as u32, self.spheres.len() as u32);
        for object in &mut mesh.objects {
            object.first_triangle += triangles_before;
            object.first_sphere += spheres_before;
        }
        append(&mut self.objects, mesh.objects);
        if !mesh.colours.is_empty() {
            self.set_colours(self.positions.len(), &mesh.colours);
        }
        if !mesh.tangents.is_empty() {
            self.set_tangents(self.normals.len(), &mesh.tangents);
        }
        append(&mut self.positions, mesh.positions);
        append(&mut self.normals, mesh.normals);
        append(&mut self.texcoords, mesh.texcoords);
        append(&mut self.triangles, mesh.triangles);
        append(&mut self.spheres, mesh.spheres);
        append(&mut self.lights, mesh.lights);
        if material.is_none() {
            append(&mut self.materials, mesh.materials);
        }
        append(&mut self.warnings, mesh.warnings);
        Ok(())
    }
}

/// A placement given as a 4x4 matrix, row-major, world from object (as TOML's
/// `matrix` and the rows of an `[[instances]]` file hold it), checked: every value
/// finite, the last row `0 0 0 1` (an affine map: no projection), and the linear part
/// invertible in `f32` (a singular matrix flattens the mesh, and its normals have no
/// direction). The message says what is wrong.
pub fn affine_from_rows(m: &[f64; 16]) -> Result<Affine3A, String> {
    if let Some(bad) = m
        .iter()
        .find(|v| !v.is_finite() || !(**v as f32).is_finite())
    {
        return Err(format!("non-finite value {bad:e} in the matrix"));
    }
    if m[12..] != [0.0, 0.0, 0.0, 1.0] {
        return Err(format!(
            "the last row is {} {} {} {}, not 0 0 0 1 (an affine placement)",
            m[12], m[13], m[14], m[15]
        ));
    }
    let linear = DMat3::from_cols_array(&[m[0], m[4], m[8], m[1], m[5], m[9], m[2], m[6], m[10]]);
    let det = linear.determinant();
    // Relative to the size of the entries, so that a tiny but well-shaped scale
    // (millimetres to kilometres) is not refused, while rows that are (nearly)
    // multiples of one another are.
    let size = linear
        .to_cols_array()
        .iter()
        .fold(0.0f64, |a, v| a.max(v.abs()));
    if det == 0.0 || !det.is_finite() || det.abs() <= 1e-12 * size * size * size {
        return Err(format!(
            "singular matrix (determinant {det}): it flattens the mesh"
        ));
    }
    let affine = Affine3A::from_mat3_translation(
        linear.as_mat3(),
        Vec3::new(m[3] as f32, m[7] as f32, m[11] as f32),
    );
    let inverse = affine.inverse();
    if !inverse.is_finite() || !affine.matrix3.inverse().transpose().is_finite() {
        return Err("singular matrix: its inverse is not finite in 32-bit floats".into());
    }
    Ok(affine)
}

impl SceneDescription {
    /// Writes every copy its instances place into the description's own arrays, as
    /// if each had been read on its own: the one-level scene that a two-level one
    /// stands for (and what a mesh file with instances becomes when a TOML mesh
    /// places it).
    ///
    /// # Errors
    /// More vertices or triangles in all than 32-bit indices can address.
    pub fn flatten_instances(&mut self) -> Result<(), ParseErrorKind> {
        let meshes = std::mem::take(&mut self.meshes);
        for instance in std::mem::take(&mut self.instances) {
            let Some(mesh) = meshes.get(instance.mesh as usize) else {
                continue;
            };
            let mut copy = SceneDescription {
                lights: Vec::new(),
                ..mesh.clone()
            };
            if instance.winding_kept && instance.world_from_object.matrix3.determinant() < 0.0 {
                for (i, t) in copy.triangles.iter_mut().enumerate() {
                    t.positions.swap(1, 2);
                    if let Some(Some(n)) = copy.triangle_normals.get_mut(i) {
                        n.swap(1, 2);
                    }
                    if let Some(Some(uv)) = copy.triangle_texcoords.get_mut(i) {
                        uv.swap(1, 2);
                    }
                }
            }
            // Materials are this description's already.
            let own = std::mem::take(&mut copy.materials);
            debug_assert!(own.is_empty());
            self.append_geometry(copy, &Transform::from_affine(&instance.world_from_object))?;
        }
        Ok(())
    }

    /// [`SceneDescription::append`] of a mesh whose material ids are this
    /// description's.
    fn append_geometry(
        &mut self,
        mesh: SceneDescription,
        transform: &Transform,
    ) -> Result<(), ParseErrorKind> {
        // With this description's materials set aside, `append` shifts no id.
        let materials = std::mem::take(&mut self.materials);
        let result = self.append(mesh, transform, None);
        let appended = std::mem::replace(&mut self.materials, materials);
        debug_assert!(appended.is_empty());
        result
    }

    /// Adds `mesh` to [`SceneDescription::meshes`], to be placed by instances only:
    /// its material ids shifted to follow this description's materials (its own
    /// appended), or all set to `material`. Returns its index.
    ///
    /// # Errors
    /// A mesh with spheres (instances place triangle meshes), or more meshes than
    /// 32-bit indices address.
    pub fn add_instanced_mesh(
        &mut self,
        mesh: SceneDescription,
        material: Option<MaterialId>,
    ) -> Result<u32, ParseErrorKind> {
        let mut mesh = mesh;
        if !mesh.instances.is_empty() {
            mesh.flatten_instances()?;
        }
        if !mesh.spheres.is_empty() {
            return Err(ParseErrorKind::TomlValue {
                key: "mesh.id".into(),
                message: "a mesh placed by instances cannot hold spheres".into(),
            });
        }
        let index =
            u32::try_from(self.meshes.len()).map_err(|_| ParseErrorKind::TooMany("meshes"))?;
        let material_offset = self.materials.len() as u32;
        for t in &mut mesh.triangles {
            t.material = material.unwrap_or(MaterialId(t.material.0 + material_offset));
        }
        if material.is_none() {
            append(&mut self.materials, std::mem::take(&mut mesh.materials));
        }
        append(&mut self.warnings, std::mem::take(&mut mesh.warnings));
        mesh.materials = Vec::new();
        self.meshes.push(mesh);
        Ok(index)
    }

    /// Places mesh `mesh` (of [`SceneDescription::meshes`]) by `world_from_object`,
    /// with the lights its file holds, moved likewise.
    pub fn add_instance(&mut self, mesh: u32, world_from_object: Affine3A, winding_kept: bool) {
        if let Some(m) = self.meshes.get(mesh as usize) {
            for l in &m.lights {
                let mut l = *l;
                l.position = world_from_object.transform_point3(l.position);
                if let LightKind::Spot { direction, .. } | LightKind::Directional { direction } =
                    &mut l.kind
                {
                    *direction = world_from_object
                        .transform_vector3(*direction)
                        .normalize_or(*direction);
                }
                self.lights.push(l);
            }
        }
        self.instances.push(InstanceDesc {
            mesh,
            world_from_object,
            winding_kept,
        });
    }
}

/// `to` followed by `from`, moving `from` over whole when `to` is empty.
fn append<T>(to: &mut Vec<T>, mut from: Vec<T>) {
    if to.is_empty() {
        *to = from;
    } else {
        to.append(&mut from);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::description::{SphereDesc, TriangleDesc};
    use crate::material::{Light, Material};

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-5
    }

    #[test]
    fn scale_then_rotate_then_translate() {
        let t = Transform::new(Vec3::new(2.0, 1.0, 1.0), Vec3::new(0.0, 90.0, 0.0), Vec3::X);
        // (1,0,0) scaled to (2,0,0), turned 90 degrees about y to (0,0,-2), moved by +x.
        assert!(close(t.point(Vec3::X), Vec3::new(1.0, 0.0, -2.0)));
        // Rotations apply about x first, then z: x 90 takes +y to +z, z 90 leaves it.
        let t = Transform::new(Vec3::ONE, Vec3::new(90.0, 0.0, 90.0), Vec3::ZERO);
        assert!(close(t.point(Vec3::Y), Vec3::Z));
        assert!(close(t.point(Vec3::X), Vec3::Y));
    }

    #[test]
    fn normals_stay_perpendicular_under_non_uniform_scale() {
        // The plane x + y = 1 has normal (1,1,0); stretching x by 4 tilts the plane.
        let t = Transform::new(
            Vec3::new(4.0, 1.0, 1.0),
            Vec3::new(10.0, 20.0, 30.0),
            Vec3::ONE,
        );
        let (a, b) = (t.point(Vec3::X), t.point(Vec3::Y));
        let n = t.normal(Vec3::new(1.0, 1.0, 0.0));
        assert!((b - a).dot(n).abs() < 1e-5, "{}", (b - a).dot(n));
        assert!((t.point(Vec3::Z) - t.point(Vec3::ZERO)).dot(n).abs() < 1e-5);
        assert_eq!(t.uniform_scale(), None);
        assert_eq!(
            Transform::new(Vec3::new(-2.0, 2.0, 2.0), Vec3::ZERO, Vec3::ZERO).uniform_scale(),
            Some(2.0)
        );
    }

    #[test]
    fn append_shifts_indices_and_materials_or_overrides_them() {
        let mesh = SceneDescription {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            normals: vec![Vec3::Z],
            triangles: vec![TriangleDesc {
                positions: [0, 1, 2],
                material: MaterialId(0),
            }],
            triangle_normals: vec![Some([0, 0, 0])],
            spheres: vec![SphereDesc {
                center: Vec3::ZERO,
                radius: 1.0,
                material: MaterialId(0),
            }],
            lights: vec![Light::point(Vec3::Y, Vec3::ONE)],
            materials: vec![Material::named("m")],
            ..SceneDescription::default()
        };
        let mut all = SceneDescription::default();
        all.append(mesh.clone(), &Transform::IDENTITY, None)
            .unwrap();
        let moved = Transform::new(Vec3::splat(3.0), Vec3::ZERO, Vec3::Z);
        all.append(mesh.clone(), &moved, None).unwrap();
        all.append(mesh.clone(), &Transform::IDENTITY, Some(MaterialId(0)))
            .unwrap();
        assert_eq!(all.positions.len(), 9);
        assert_eq!(all.triangles[1].positions, [3, 4, 5]);
        assert_eq!(all.normals_of(1), Some([1, 1, 1]));
        assert_eq!(all.triangles[1].material, MaterialId(1));
        assert_eq!(all.triangles[2].material, MaterialId(0));
        assert_eq!(all.materials.len(), 2);
        assert_eq!(all.spheres[1].radius, 3.0);
        assert_eq!(all.spheres[1].center, Vec3::Z);
        assert_eq!(all.lights[1].position, Vec3::new(0.0, 3.0, 1.0));
        assert_eq!(all.positions[4], Vec3::new(3.0, 0.0, 1.0));

        let squash = Transform::new(Vec3::new(1.0, 2.0, 1.0), Vec3::ZERO, Vec3::ZERO);
        let err = all.append(mesh, &squash, None).unwrap_err();
        assert_eq!(err, ParseErrorKind::NonUniformSphereScale);
    }

    /// Normal indices stay in step with the triangles when only some meshes have
    /// them, and stay absent when none has.
    #[test]
    fn append_keeps_normal_indices_in_step() {
        let bare = SceneDescription {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            triangles: vec![
                TriangleDesc {
                    positions: [0, 1, 2],
                    material: MaterialId(0),
                };
                2
            ],
            materials: vec![Material::named("m")],
            ..SceneDescription::default()
        };
        let mut smooth = bare.clone();
        smooth.normals = vec![Vec3::Z, Vec3::X];
        smooth.triangle_normals = vec![Some([1, 1, 1]), None];
        let mut all = SceneDescription::default();
        all.append(bare.clone(), &Transform::IDENTITY, None)
            .unwrap();
        assert!(all.triangle_normals.is_empty());
        all.append(smooth, &Transform::IDENTITY, None).unwrap();
        all.append(bare, &Transform::IDENTITY, None).unwrap();
        assert_eq!(
            all.triangle_normals,
            [None, None, Some([1, 1, 1]), None, None, None]
        );
    }
}
