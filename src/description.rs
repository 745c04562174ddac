//! The scene description: what the file readers ([`crate::formats`]) produce and
//! [`crate::scene::Scene::build`] consumes. Plain data, indices resolved to 0-based,
//! nothing built yet.

use glam::Vec3A;
use rayon::prelude::*;

use crate::material::{Light, Material, MaterialId};
use crate::math::{Aabb, Float, Vec2, Vec3, try_unit};
use crate::options::{Flat, Mode, RenderOptions};

/// The default light rig of an unlit scene in full mode
/// ([`SceneDescription::add_default_light`]): a key light above and to the left of
/// the camera and a fill light at the camera, as a modeller's viewport lights a model,
/// with intensities (`key`, `fill`) and the ambient light `ambient` that every
/// material reflects by `Ka * Kd`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightRig {
    /// Intensity of the key light, above and to the left of the camera.
    pub key: Float,
    /// Intensity of the fill light, at the camera (it reaches every point the camera
    /// sees, so nothing visible is left black).
    pub fill: Float,
    /// The ambient light: `Ka` becomes `Ka * Kd * ambient`. MTL's illumination models
    /// multiply `Ka` by the ambient light `Ia` (SPEC.md's formula has `Ia = 1`); a
    /// model viewer reflects its ambient light by the diffuse colour.
    pub ambient: Float,
}

impl LightRig {
    /// The rig [`SceneDescription::add_default_light`] adds.
    pub const DEFAULT: LightRig = LightRig {
        key: 0.8,
        fill: 0.4,
        ambient: 0.1,
    };
}

/// A scene as read from files: plain data, indices resolved to 0-based, nothing
/// built yet. Shapes, lights and materials keep file order.
#[derive(Clone, Debug, Default)]
pub struct SceneDescription {
    /// `v` positions.
    pub positions: Vec<Vec3>,
    /// `vt` texture coordinates (glTF: `TEXCOORD_0`, with `v` turned up).
    pub texcoords: Vec<Vec2>,
    /// `vn` normals, as written (not normalized).
    pub normals: Vec<Vec3>,
    /// Vertex tangents a file gives (glTF's `TANGENT`), by normal index: entry `i`
    /// belongs to the corners whose normal is `normals[i]`. `xyz` is a unit tangent
    /// along the texture's `u`, `w` (+1 or -1) the sign of the bitangent
    /// `w * cross(normal, tangent)`; a zero entry (`w = 0`) is none. Empty when no
    /// vertex has one; it may be shorter than `normals`, the vertices past its end
    /// having none ([`SceneDescription::set_tangents`]). Corners without one get
    /// MikkTSpace tangents at [`crate::Scene::build`], where their material has a
    /// normal or bump map or is anisotropic.
    pub tangents: Vec<glam::Vec4>,
    /// Vertex colours, linear RGB, by position index (glTF's `COLOR_0`, PLY's
    /// `red green blue`, OBJ's `v x y z r g b`): they multiply the diffuse (or base)
    /// colour of the material where they are interpolated. Empty when no vertex
    /// has one, so that uncoloured meshes store nothing; it may be shorter than
    /// `positions`, the vertices past its end being white (a coloured mesh appended
    /// to an uncoloured one pads it: [`SceneDescription::set_colours`]).
    pub colours: Vec<Vec3>,
    /// Triangles after splitting polygons into fans.
    pub triangles: Vec<TriangleDesc>,
    /// Indices into [`SceneDescription::normals`] of each triangle's corners, in step
    /// with `triangles` (`None` where a corner has none); or empty, when no triangle
    /// has normals. (Kept apart from [`TriangleDesc`], as texture coordinates are, so
    /// that meshes without normals, such as most scans, store 16 bytes a triangle
    /// rather than 32.)
    pub triangle_normals: Vec<Option<[u32; 3]>>,
    /// Indices into [`SceneDescription::texcoords`] of each triangle's corners, in
    /// step with `triangles` (`None` where a corner has none); or empty, when no
    /// triangle has texture coordinates or no material has a map to use them with.
    /// (Kept apart from [`TriangleDesc`] so that untextured meshes, the large ones,
    /// neither store nor copy them.)
    pub triangle_texcoords: Vec<Option<[u32; 3]>>,
    /// `S` spheres.
    pub spheres: Vec<SphereDesc>,
    /// `P` lights.
    pub lights: Vec<Light>,
    /// Materials of all `mtllib` files in order, then the fallback material if any
    /// shape needed it.
    pub materials: Vec<Material>,
    /// Light from infinitely far away (path mode), if the scene or a flag sets one.
    pub environment: Option<crate::lights::environment::EnvironmentDesc>,
    /// What camera rays that leave the scene see in path mode, if not the
    /// environment.
    pub background: Option<Vec3>,
    /// Whether full mode's default light rig lights the scene (set by
    /// [`SceneDescription::add_default_light`]). Full mode then shows a model as a
    /// viewer would, beyond SPEC's rules, which scenes with lights of their own keep:
    /// physically based surfaces reflect path mode's studio
    /// ([`crate::lights::environment::studio_radiance`]; the rig has no surroundings
    /// for a metal to mirror), and shadow rays at grazing light leave smooth meshes
    /// from the surface their vertex normals describe ([`crate::Hit::lift`]).
    pub lit_by_rig: bool,
    /// The named objects (a mesh file, a glTF node with a mesh), in the order they
    /// were read: each covers the triangles and spheres from its starts up to the
    /// next object's (see [`ObjectDesc`]). Empty when the reader named none.
    pub objects: Vec<ObjectDesc>,
    /// Non-fatal problems, each naming file and line, for the caller to show.
    pub warnings: Vec<String>,
    /// Meshes placed only by [`SceneDescription::instances`], each stored once
    /// whatever the number of its copies: geometry alone (positions, normals,
    /// texture coordinates, triangles and their indices; no spheres, lights or
    /// materials), in its own object space, its material ids indexing this
    /// description's `materials`.
    pub meshes: Vec<SceneDescription>,
    /// Copies of [`SceneDescription::meshes`], each with its own placement.
    pub instances: Vec<InstanceDesc>,
}

/// One copy of a mesh of [`SceneDescription::meshes`] placed in the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstanceDesc {
    /// Index into [`SceneDescription::meshes`].
    pub mesh: u32,
    /// The placement: world from object, an invertible affine map (the readers check
    /// it is finite and not singular).
    pub world_from_object: glam::Affine3A,
    /// Whether a mirroring placement keeps the mesh's front side: glTF turns the
    /// winding of a mirrored mesh back, so that its front stays its front. Otherwise
    /// (TOML's placements) the front follows the winding as placed, as a flattened
    /// copy's does.
    pub winding_kept: bool,
}

impl InstanceDesc {
    /// `bounds` (a box in the mesh's object space) placed in the world: the box
    /// around its eight corners moved.
    pub fn world_bounds(&self, bounds: Aabb) -> Aabb {
        if bounds.min.cmpgt(bounds.max).any() {
            return Aabb::EMPTY;
        }
        (0..8).fold(Aabb::EMPTY, |b, corner| {
            let pick = |bit: u32, lo: Float, hi: Float| if corner & bit == 0 { lo } else { hi };
            let p = Vec3::new(
                pick(1, bounds.min.x, bounds.max.x),
                pick(2, bounds.min.y, bounds.max.y),
                pick(4, bounds.min.z, bounds.max.z),
            );
            b.grow(self.world_from_object.transform_point3(p))
        })
    }
}

/// Where an object begins in a [`SceneDescription`]: it holds the triangles from
/// `first_triangle` and the spheres from `first_sphere` up to the next object's
/// starts (or the end). Object ids (the `object_id` output) are positions in
/// [`SceneDescription::objects`]; shapes before the first object form an unnamed
/// object of their own, numbered first.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ObjectDesc {
    /// The object's name: a glTF node's name (or `node N`), a mesh file's name.
    pub name: String,
    /// Index of its first triangle in [`SceneDescription::triangles`].
    pub first_triangle: u32,
    /// Index of its first sphere in [`SceneDescription::spheres`].
    pub first_sphere: u32,
}

impl ObjectDesc {
    /// An object named `name` holding the shapes that `description` gets next.
    pub fn next_in(description: &SceneDescription, name: String) -> ObjectDesc {
        ObjectDesc {
            name,
            first_triangle: description.triangles.len() as u32,
            first_sphere: description.spheres.len() as u32,
        }
    }
}

impl SceneDescription {
    /// The texture coordinate indices of triangle `index`'s corners, if it has them.
    #[inline]
    pub fn texcoords_of(&self, index: usize) -> Option<[u32; 3]> {
        self.triangle_texcoords.get(index).copied().flatten()
    }

    /// The normal indices of triangle `index`'s corners, if it has them.
    #[inline]
    pub fn normals_of(&self, index: usize) -> Option<[u32; 3]> {
        self.triangle_normals.get(index).copied().flatten()
    }

    /// The vertex colour of position `index`: white where none is given.
    #[inline]
    pub fn colour_of(&self, index: u32) -> Vec3 {
        self.colours
            .get(index as usize)
            .copied()
            .unwrap_or(Vec3::ONE)
    }

    /// Sets the colours of the positions from `first` on to `colours`, the positions
    /// before it that have none white.
    pub fn set_colours(&mut self, first: usize, colours: &[Vec3]) {
        self.colours.resize(first, Vec3::ONE);
        self.colours.extend_from_slice(colours);
    }

    /// Sets the tangents of the normals from `first` on to `tangents`, the normals
    /// before it that have none given none (zero).
    pub fn set_tangents(&mut self, first: usize, tangents: &[glam::Vec4]) {
        self.tangents.resize(first, glam::Vec4::ZERO);
        self.tangents.extend_from_slice(tangents);
    }

    /// Whether some triangle has a corner with a vertex colour, and so which
    /// materials [`crate::Scene::build`] lets vertex colours multiply.
    pub fn has_colours(&self) -> bool {
        !self.colours.is_empty() || self.meshes.iter().any(|m| !m.colours.is_empty())
    }

    /// Appends a triangle with its normal indices, keeping
    /// [`SceneDescription::triangle_normals`] in step (or empty while no triangle has
    /// normals).
    pub fn push_triangle(&mut self, triangle: TriangleDesc, normals: Option<[u32; 3]>) {
        self.triangles.push(triangle);
        if normals.is_some() || !self.triangle_normals.is_empty() {
            self.triangle_normals.resize(self.triangles.len() - 1, None);
            self.triangle_normals.push(normals);
        }
    }

    /// The box around every triangle and sphere (not the lights, nor vertices no face
    /// uses); empty for a scene without shapes.
    pub fn bounds(&self) -> Aabb {
        // Each corner of a triangle grows a box of its own, in SIMD lanes, so that
        // the three do not wait for each other (one box grown by every corner in
        // turn, lane by lane, took a tenth of the dragon's build stage). `p.min(b)`
        // leaves `b` as it was where `p` is NaN, as `Aabb::grow` does.
        type Corners = [(Vec3A, Vec3A); 3];
        const EMPTY: Corners = [(Vec3A::INFINITY, Vec3A::NEG_INFINITY); 3];
        let corners = self
            .triangles
            .par_iter()
            .fold(
                || EMPTY,
                |mut boxes, t| {
                    for (b, &i) in boxes.iter_mut().zip(&t.positions) {
                        let p = Vec3A::from(self.positions[i as usize]);
                        *b = (p.min(b.0), p.max(b.1));
                    }
                    boxes
                },
            )
            .reduce(
                || EMPTY,
                |a, b| std::array::from_fn(|k| (a[k].0.min(b[k].0), a[k].1.max(b[k].1))),
            );
        let triangles = corners.iter().fold(Aabb::EMPTY, |acc, &(min, max)| {
            acc.union(Aabb {
                min: min.into(),
                max: max.into(),
            })
        });
        let shapes = self.spheres.iter().fold(triangles, |b, s| {
            let r = Vec3::splat(s.radius);
            b.union(Aabb {
                min: s.center - r,
                max: s.center + r,
            })
        });
        if self.instances.is_empty() {
            return shapes;
        }
        let mesh_bounds: Vec<Aabb> = self.meshes.iter().map(SceneDescription::bounds).collect();
        (self.instances.iter())
            .filter_map(|i| Some(i.world_bounds(*mesh_bounds.get(i.mesh as usize)?)))
            .fold(shapes, Aabb::union)
    }

    /// What the framing camera fits in the image
    /// ([`crate::options::PartialOptions::framed_by`]): every triangle corner, the
    /// spheres, and the box of each instance placed.
    pub fn extent(&self) -> Extent {
        let mut used = vec![false; self.positions.len()];
        for t in &self.triangles {
            for &i in &t.positions {
                used[i as usize] = true;
            }
        }
        let points = (self.positions.iter().zip(used))
            .filter_map(|(&p, used)| used.then_some(p))
            .collect();
        let mesh_bounds: Vec<Aabb> = self.meshes.iter().map(SceneDescription::bounds).collect();
        // The triangles' winding, for a flat scene's side: their normals weighted by
        // area, summed, and their areas (twice each, as cross products are).
        let corner = |i: u32| self.positions[i as usize].as_dvec3();
        let (facing, area) = (self.triangles.par_iter())
            .map(|t| {
                let [a, b, c] = t.positions.map(corner);
                let n = (b - a).cross(c - a);
                // Triangles at non-finite corners are dropped later.
                if n.is_finite() {
                    (n, n.length())
                } else {
                    (glam::DVec3::ZERO, 0.0)
                }
            })
            .reduce(|| (glam::DVec3::ZERO, 0.0), |x, y| (x.0 + y.0, x.1 + y.1));
        Extent {
            facing: (facing, area),
            points,
            spheres: self.spheres.iter().map(|s| (s.center, s.radius)).collect(),
            boxes: (self.instances.iter())
                .filter_map(|i| Some(i.world_bounds(*mesh_bounds.get(i.mesh as usize)?)))
                .filter(|b| !b.is_empty())
                .collect(),
        }
    }

    /// Triangles in the world counting every copy: those of the description itself
    /// and, for each instance, its mesh's.
    pub fn instanced_triangle_count(&self) -> u64 {
        let copies = (self.instances.iter())
            .filter_map(|i| self.meshes.get(i.mesh as usize))
            .map(|m| m.triangles.len() as u64)
            .sum::<u64>();
        self.triangles.len() as u64 + copies
    }

    /// Triangles stored: those of the description and of each of its meshes once.
    pub fn unique_triangle_count(&self) -> u64 {
        let meshes = self
            .meshes
            .iter()
            .map(|m| m.triangles.len() as u64)
            .sum::<u64>();
        self.triangles.len() as u64 + meshes
    }

    /// Whether nothing lights the scene: no point light, and no shapes whose material
    /// emits (`Ke`) enough to light it
    /// ([`crate::lights::environment::emitters_light_the_scene`], by their area times
    /// their mean `Ke`: a few LEDs on a model do not), emission through a texture map
    /// not counting (a screen or LEDs painted on a model are decoration). A scene all
    /// of whose surfaces emit is unlit too: its emitters have nothing else to light
    /// (exporters write `Ke 0.1` into every material of some models).
    pub fn is_unlit(&self) -> bool {
        self.unlit_reason().is_some()
    }

    /// Why the scene is unlit ([`SceneDescription::is_unlit`]), as the default light's
    /// warning says it; `None` for a lit scene.
    fn unlit_reason(&self) -> Option<&'static str> {
        if !self.lights.is_empty() {
            return None;
        }
        // Emission through a texture (glTF's emissive maps: screens, LEDs, labels
        // painted on a model) is decoration: it glows but is not what lights the
        // model. Uniform emission counts by its area.
        let emission: Vec<Float> = (self.materials.iter())
            .map(|m| {
                let textured = m.maps.as_ref().is_some_and(|maps| maps.emission.is_some());
                let e = m.emission.max(Vec3::ZERO);
                if textured {
                    0.0
                } else {
                    (e.x + e.y + e.z) / 3.0
                }
            })
            .collect();
        const NO_LIGHTS: &str = "the scene has no lights (no light sources, no emitting surfaces)";
        if !emission.iter().any(|&e| e > 0.0) {
            return Some(NO_LIGHTS);
        }
        let of = |id: MaterialId| emission.get(id.0 as usize).copied().unwrap_or(0.0);
        let mut power = 0.0f64;
        // Whether some surface does not emit: something the emitters could light.
        let mut receiver = false;
        for t in &self.triangles {
            let e = of(t.material);
            receiver |= e == 0.0;
            if e > 0.0 {
                let [a, b, c] = t.positions.map(|i| self.positions[i as usize]);
                power += f64::from(e * 0.5 * (b - a).cross(c - a).length());
            }
        }
        for s in &self.spheres {
            let e = of(s.material);
            receiver |= e == 0.0;
            power += f64::from(e * 4.0 * std::f32::consts::PI * s.radius * s.radius);
        }
        // Each copy of an emitting mesh, by the area it has where it is placed.
        for instance in &self.instances {
            let Some(mesh) = self.meshes.get(instance.mesh as usize) else {
                continue;
            };
            for t in &mesh.triangles {
                let e = of(t.material);
                receiver |= e == 0.0;
                if e > 0.0 {
                    let [a, b, c] = t.positions.map(|i| {
                        instance
                            .world_from_object
                            .transform_point3(mesh.positions[i as usize])
                    });
                    power += f64::from(e * 0.5 * (b - a).cross(c - a).length());
                }
            }
        }
        if power == 0.0 {
            // Emitting materials that no shape uses.
            return Some(NO_LIGHTS);
        }
        if !receiver {
            return Some("every surface of the scene emits ('Ke'), lighting nothing else");
        }
        let bounds = self.bounds();
        let radius = (bounds.max - bounds.min).length() * 0.5;
        let lit = crate::lights::environment::emitters_light_the_scene(power as Float, radius);
        (!lit).then_some("the scene's emitters ('Ke') are too small to light it")
    }

    /// Lights a scene that has no light and no emitter ([`SceneDescription::is_unlit`])
    /// for the mode of `options`, with one warning saying so; does nothing to a lit
    /// scene, whose lighting stays exactly the rules of `docs/spec-renderer.md`.
    ///
    /// In full mode, unless `options.default_light` is off, it adds
    /// [`LightRig::DEFAULT`] around the camera of `options` and multiplies every `Ka` by
    /// `Kd` and the rig's ambient light: exported models carry `Ka 1 1 1` (Blender,
    /// Wings 3D) whatever their colour, which added in full would wash every colour
    /// out, and as a grey would make a black model as grey as the backdrop. A material
    /// whose `Ns` is below 1 (no highlight) loses its `Ks`, which SPEC's formula would
    /// add flat. Path mode lights an unlit scene with a studio environment instead
    /// ([`crate::integrators::path`]), under the same switch. Depth and normal modes
    /// need no light.
    pub fn add_default_light(&mut self, options: &RenderOptions) {
        self.add_default_light_off_by(options, None);
    }

    /// [`SceneDescription::add_default_light`], whose warning, when the default light
    /// is off, names what turned it off (`off_by`: `--no-default-light`, or the scene
    /// file's line and key), so that a user who did not pass the flag finds the
    /// file's `render.default_light = false`.
    pub fn add_default_light_off_by(
        &mut self,
        options: &RenderOptions,
        off_by: Option<&crate::options::Origin>,
    ) {
        let Some(reason) = self.unlit_reason() else {
            return;
        };
        if options.mode == Mode::Path && self.environment.is_some() {
            return;
        }
        let off = match off_by {
            Some(origin) => format!(" (the default light is off: {origin})"),
            None => String::new(),
        };
        let message = match (options.mode, options.default_light) {
            (Mode::Depth | Mode::Normal, _) => return,
            (Mode::Full, true) => {
                "lit by a default light rig at the camera (--no-default-light turns it off)"
                    .to_string()
            }
            (Mode::Full, false) => format!("full mode shows only its ambient colour (Ka){off}"),
            (Mode::Path, true) => {
                "path mode lights it with a studio environment (--no-default-light turns it off)"
                    .to_string()
            }
            (Mode::Path, false) => format!("path mode renders it black{off}"),
        };
        self.warnings.push(format!("{reason}: {message}"));
        if options.mode != Mode::Full || !options.default_light {
            return;
        }
        let rig = LightRig::DEFAULT;
        let eye = options.look_from;
        let to_target = options.look_to - eye;
        let forward = try_unit(to_target).unwrap_or(Vec3::NEG_Z);
        let right = try_unit(forward.cross(options.up)).unwrap_or(Vec3::X);
        let up = right.cross(forward);
        let offset = 0.5 * up - 0.5 * right;
        let mut key = eye + to_target.length() * offset;
        if !key.is_finite() {
            // The squared distance of a camera 1e20 away overflows `f32` (an infinite
            // light makes every pixel NaN): again in f64. Where even the position
            // does not fit, the key light sits at the eye with the fill light.
            let distance = to_target.as_dvec3().length();
            key = (eye.as_dvec3() + distance * offset.as_dvec3()).as_vec3();
        }
        self.lights.push(Light::point(
            if key.is_finite() { key } else { eye },
            Vec3::splat(rig.key),
        ));
        self.lights.push(Light::point(eye, Vec3::splat(rig.fill)));
        self.lit_by_rig = true;
        for material in &mut self.materials {
            // The surroundings' light is reflected by the diffuse colour, as a model
            // viewer (which reads no `Ka`) shows it; `Ka` scales it. Exporters write
            // `Ka 1 1 1` whatever the colour (Blender): a grey ambient added to a
            // black plastic made it as grey as the backdrop.
            material.ambient *= material.diffuse * rig.ambient;
            // An exponent below 1 defines no highlight: SPEC's formula would add `Ks`
            // flat wherever the light reaches (`max(0, x)^0 = 1`), washing the model
            // out, where the exporting tool shows a matte surface (Blender reads
            // `Ns 0` as fully rough). 3ds Max writes `Ks 0.9` with `Ns 0`.
            if material.shininess < 1.0 {
                material.specular = Vec3::ZERO;
            }
        }
    }
}

/// A triangle of a description: indices into its arrays (normals and texture
/// coordinates are in [`SceneDescription::triangle_normals`] and
/// [`SceneDescription::triangle_texcoords`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleDesc {
    /// Indices into [`SceneDescription::positions`].
    pub positions: [u32; 3],
    /// The material.
    pub material: MaterialId,
}

const _: () = assert!(size_of::<TriangleDesc>() == 16);

/// A sphere of a description.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereDesc {
    /// Centre.
    pub center: Vec3,
    /// Radius, not negative.
    pub radius: Float,
    /// The material.
    pub material: MaterialId,
}

/// The shapes of a scene as the framing camera sees them
/// ([`SceneDescription::extent`]): points, spheres and boxes.
#[derive(Clone, Debug, Default)]
pub struct Extent {
    /// The sum of the triangles' area-weighted normals, and of their areas.
    facing: (glam::DVec3, f64),
    points: Vec<Vec3>,
    spheres: Vec<(Vec3, Float)>,
    boxes: Vec<Aabb>,
}

impl Extent {
    /// The largest `p.w` over the scene's points `p` (its convex hull's support
    /// function), in f64 as the framing is; minus infinity for no shapes.
    pub fn support(&self, w: glam::DVec3) -> f64 {
        let dot = |p: Vec3| p.as_dvec3().dot(w);
        let points = (self.points.par_iter())
            .map(|&p| dot(p))
            .reduce(|| f64::NEG_INFINITY, f64::max);
        let spheres = (self.spheres.iter())
            .map(|&(c, r)| dot(c) + f64::from(r) * w.length())
            .fold(points, f64::max);
        (self.boxes.iter())
            .map(|b| {
                (b.min.as_dvec3() * w)
                    .max(b.max.as_dvec3() * w)
                    .element_sum()
            })
            .fold(spheres, f64::max)
    }

    /// The unit normal of the plane the scene lies in, if it is flat: points alone
    /// (no spheres, no instances) that span a plane and lie no farther from it than
    /// [`FLAT_THICKNESS`] of the scene's largest width (a polygon or a decal, with
    /// its coordinates rounded to 6 digits). The framing camera then sees it face-on,
    /// as it sees a scene flat in x, y or z.
    pub fn flat_normal(&self) -> Option<Flat> {
        use glam::DVec3;
        if !self.spheres.is_empty() || !self.boxes.is_empty() || self.points.len() < 3 {
            return None;
        }
        let count = self.points.len() as f64;
        let sum = |f: &(dyn Fn(DVec3) -> [f64; 6] + Sync)| {
            (self.points.par_iter())
                .map(|&p| f(p.as_dvec3()))
                .reduce(|| [0.0; 6], |a, b| std::array::from_fn(|i| a[i] + b[i]))
        };
        let [x, y, z, ..] = sum(&|p| [p.x, p.y, p.z, 0.0, 0.0, 0.0]);
        let centroid = DVec3::new(x, y, z) / count;
        let [xx, xy, xz, yy, yz, zz] = sum(&|p| {
            let d = p - centroid;
            [
                d.x * d.x,
                d.x * d.y,
                d.x * d.z,
                d.y * d.y,
                d.y * d.z,
                d.z * d.z,
            ]
        });
        // The covariance of points in a plane has the plane's normal as its null
        // vector: every row is perpendicular to it, so the largest cross product of
        // two rows lies along it.
        let rows = [
            DVec3::new(xx, xy, xz),
            DVec3::new(xy, yy, yz),
            DVec3::new(xz, yz, zz),
        ];
        let normal = [
            rows[0].cross(rows[1]),
            rows[0].cross(rows[2]),
            rows[1].cross(rows[2]),
        ]
        .into_iter()
        .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))?
        .try_normalize()?;
        let width = |w: DVec3| self.support(w) + self.support(-w);
        let widest = [DVec3::X, DVec3::Y, DVec3::Z]
            .map(width)
            .into_iter()
            .fold(0.0, f64::max);
        if width(normal) > FLAT_THICKNESS * widest {
            return None;
        }
        let (facing, area) = self.facing;
        Some(match facing.dot(normal) {
            along if along < -0.5 * area => Flat {
                normal: -normal,
                faced: true,
            },
            along => Flat {
                normal,
                faced: along > 0.5 * area,
            },
        })
    }
}

/// How thin, against its largest width, a scene is flat for the framing camera
/// ([`Extent::flat_normal`]).
pub const FLAT_THICKNESS: f64 = 1e-3;

#[cfg(test)]
mod tests {
    use super::*;

    /// The box grown corner by corner in SIMD lanes, three boxes at a time, is the
    /// one `Aabb::grow` makes corner after corner; a NaN coordinate (only a
    /// description made by a library caller has one: the readers drop the triangles
    /// using it) is left out of the box, as `f32::min` and `max` leave it out.
    #[test]
    fn bounds_are_those_of_growing_by_every_corner() {
        let mut d = SceneDescription::default();
        let mut state = 7u32;
        let mut next = || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as Float / (1 << 24) as Float * 20.0 - 10.0
        };
        for _ in 0..3000 {
            d.positions.push(Vec3::new(next(), next(), next()));
        }
        let count = d.positions.len() as u32;
        for i in 0..5000u32 {
            d.triangles.push(TriangleDesc {
                positions: [i % count, (i * 7 + 1) % count, (i * 13 + 2) % count],
                material: MaterialId(0),
            });
        }
        let grown = |d: &SceneDescription| {
            d.triangles.iter().fold(Aabb::EMPTY, |b, t| {
                t.positions
                    .iter()
                    .fold(b, |b, &i| b.grow(d.positions[i as usize]))
            })
        };
        assert_eq!(d.bounds(), grown(&d));
        // A corner at NaN, 50, NaN grows the box's top alone.
        let mut with_nan = d.clone();
        with_nan
            .positions
            .push(Vec3::new(Float::NAN, 50.0, Float::NAN));
        with_nan.triangles.push(TriangleDesc {
            positions: [0, 1, count],
            material: MaterialId(0),
        });
        let mut expected = grown(&d);
        expected.max.y = 50.0;
        assert_eq!(with_nan.bounds(), expected);
        assert_eq!(SceneDescription::default().bounds(), Aabb::EMPTY);
    }
}
