//! What `raytracer info` reports about a scene: counts, bounds, materials in use, the
//! memory a render will take, and warnings. Computed from the description alone, so
//! it is quick even for scenes whose BVH takes seconds to build.

use std::fmt;
use std::mem::size_of;

use super::{SceneDescription, SphereDesc, TriangleDesc};
use crate::bvh::WideNode;
use crate::material::MaterialId;
use crate::math::{Aabb, Vec2, Vec3};
use crate::options::RenderOptions;
use crate::shapes::{Sphere, Triangle, TrianglePacket};

/// Average primitives per four-lane packet assumed by the memory estimate: leaves
/// hold what the SAH builder leaves together, rarely a full four. Measured 2.98 on
/// the Stanford dragon (871,308 triangles in 292,149 packets).
const TYPICAL_PACKET_FILL: f64 = 2.9;
/// Average packets per wide BVH node: 3.28 on the dragon (89,106 nodes).
const TYPICAL_PACKETS_PER_NODE: f64 = 3.2;

/// A summary of a scene description.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneSummary {
    /// Vertex positions.
    pub vertices: usize,
    /// Triangles, degenerate ones included.
    pub triangles: usize,
    /// Triangles the renderer drops, by [`Triangle::is_degenerate`]: zero area, or
    /// a normal beyond `f32`.
    pub degenerate_triangles: usize,
    /// Triangles in the world counting every copy instances place (equal to
    /// `triangles` in a scene without instances).
    pub instanced_triangles: u64,
    /// Instances placing meshes that are stored once.
    pub instances: usize,
    /// Meshes stored once and placed by instances.
    pub meshes: usize,
    /// Spheres.
    pub spheres: usize,
    /// Point lights.
    pub lights: usize,
    /// Every material with how many shapes use it, in [`crate::MaterialId`] order.
    pub materials: Vec<MaterialUse>,
    /// Box around every triangle and sphere (empty if there are none).
    pub bounds: Aabb,
    /// The memory a render will take.
    pub memory: MemoryEstimate,
    /// Problems worth knowing before rendering: those found while reading, unused
    /// materials, degenerate triangles, no lights.
    pub warnings: Vec<String>,
}

/// How much one material is used.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MaterialUse {
    /// The material's name.
    pub name: String,
    /// Triangles that use it (degenerate ones excluded).
    pub triangles: usize,
    /// Spheres that use it.
    pub spheres: usize,
}

/// Bytes a render needs, estimated from the sizes of the renderer's data structures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MemoryEstimate {
    /// The description as read (freed once the scene is built).
    pub description: usize,
    /// Geometry of every primitive, in SIMD packets of up to four, assuming the
    /// typical packet fill.
    pub shapes: usize,
    /// Material and normal indices of every primitive.
    pub shading: usize,
    /// Unit vertex normals.
    pub vertex_normals: usize,
    /// Wide BVH nodes, assuming the typical packets per node.
    pub bvh: usize,
    /// The linear film and the 8-bit image made from it.
    pub film: usize,
}

impl MemoryEstimate {
    /// Memory held while rendering: the built scene and the film.
    pub fn render_total(&self) -> usize {
        self.shapes + self.shading + self.vertex_normals + self.bvh + self.film
    }
}

impl SceneSummary {
    /// Summarises `scene`, to be rendered with `options` (which sets the film size).
    pub fn new(scene: &SceneDescription, options: &RenderOptions) -> Self {
        let mut triangle_uses = vec![0usize; scene.materials.len()];
        let mut sphere_uses = vec![0usize; scene.materials.len()];
        let mut degenerate = 0;
        let mut with_normals = 0;
        let mut bounds = Aabb::EMPTY;
        for (i, tri) in scene.triangles.iter().enumerate() {
            let [a, b, c] = tri.positions.map(|i| scene.positions[i as usize]);
            if Triangle::new(a, b, c).is_degenerate() {
                degenerate += 1;
                continue;
            }
            bounds = bounds.grow(a).grow(b).grow(c);
            triangle_uses[tri.material.0 as usize] += 1;
            with_normals += scene.normals_of(i).is_some() as usize;
        }
        // Meshes placed by instances count once here (their copies in
        // `instanced_triangles`), as they are stored once.
        for mesh in &scene.meshes {
            for (i, tri) in mesh.triangles.iter().enumerate() {
                let [a, b, c] = tri.positions.map(|i| mesh.positions[i as usize]);
                if Triangle::new(a, b, c).is_degenerate() {
                    degenerate += 1;
                    continue;
                }
                if let Some(uses) = triangle_uses.get_mut(tri.material.0 as usize) {
                    *uses += 1;
                }
                with_normals += mesh.normals_of(i).is_some() as usize;
            }
        }
        if !scene.instances.is_empty() {
            bounds = bounds.union(scene.bounds());
        }
        for s in &scene.spheres {
            let sphere = Sphere {
                center: s.center,
                radius: s.radius,
            };
            bounds = bounds.union(sphere.bounds());
            sphere_uses[s.material.0 as usize] += 1;
        }
        let materials: Vec<MaterialUse> = scene
            .materials
            .iter()
            .zip(triangle_uses.iter().zip(&sphere_uses))
            .map(|(m, (&triangles, &spheres))| MaterialUse {
                name: m.name.clone(),
                triangles,
                spheres,
            })
            .collect();

        let mut warnings = scene.warnings.clone();
        for m in materials.iter().filter(|m| m.triangles + m.spheres == 0) {
            warnings.push(format!("material '{}' is not used", m.name));
        }
        if degenerate > 0 {
            warnings.push(format!(
                "{degenerate} degenerate (zero-area) triangle{} will be skipped",
                if degenerate == 1 { "" } else { "s" }
            ));
        }
        if scene.is_unlit() {
            warnings.push(
                "no lights (no light sources, no emitting surfaces): render adds a default light rig at the camera (a studio environment in path mode) unless --no-default-light"
                    .into(),
            );
        } else if scene.lights.is_empty() {
            warnings.push("no lights: full mode shows only ambient (Ka) and emission (Ke)".into());
        }

        let unique_triangles = scene.unique_triangle_count() as usize;
        let prims = unique_triangles - degenerate + scene.spheres.len();
        let pixels = options.width as usize * options.height as usize;
        let packets = (prims as f64 / TYPICAL_PACKET_FILL).ceil();
        let wide_nodes = if prims == 0 {
            0
        } else {
            ((packets / TYPICAL_PACKETS_PER_NODE).ceil() as usize).max(1)
        };
        let memory = MemoryEstimate {
            description: scene.positions.len() * size_of::<Vec3>()
                + scene.normals.len() * size_of::<Vec3>()
                + scene.tangents.len() * size_of::<glam::Vec4>()
                + scene.texcoords.len() * size_of::<Vec2>()
                + scene.triangles.len() * size_of::<TriangleDesc>()
                + scene.triangle_normals.len() * size_of::<Option<[u32; 3]>>()
                + scene.triangle_texcoords.len() * size_of::<Option<[u32; 3]>>()
                + scene.spheres.len() * size_of::<SphereDesc>()
                + (scene.meshes.iter())
                    .map(|m| {
                        (m.positions.len() + m.normals.len()) * size_of::<Vec3>()
                            + m.triangles.len() * size_of::<TriangleDesc>()
                    })
                    .sum::<usize>()
                + scene.instances.len() * size_of::<crate::description::InstanceDesc>(),
            shapes: packets as usize * size_of::<TrianglePacket>(),
            // A material per primitive, and its normals' indices if some triangle
            // has vertex normals.
            shading: prims
                * (size_of::<MaterialId>()
                    + if with_normals > 0 {
                        size_of::<[u32; 3]>()
                    } else {
                        0
                    }),
            vertex_normals: if with_normals > 0 {
                scene.normals.len() * size_of::<Vec3>()
            } else {
                0
            },
            bvh: wide_nodes * size_of::<WideNode>(),
            film: pixels * (size_of::<Vec3>() + 3),
        };
        SceneSummary {
            vertices: scene.positions.len(),
            triangles: unique_triangles,
            degenerate_triangles: degenerate,
            instanced_triangles: scene.instanced_triangle_count(),
            instances: scene.instances.len(),
            meshes: scene.meshes.len(),
            spheres: scene.spheres.len(),
            lights: scene.lights.len(),
            materials,
            bounds,
            memory,
            warnings,
        }
    }
}

/// `1234567` as `1,234,567`.
fn thousands(n: usize) -> String {
    let digits = n.to_string();
    let mut out = String::with_capacity(digits.len() * 4 / 3);
    for (i, d) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(d);
    }
    out
}

/// Bytes in MiB with one decimal.
fn mib(bytes: usize) -> String {
    format!("{:.1} MiB", bytes as f64 / (1024.0 * 1024.0))
}

fn vector(v: Vec3) -> String {
    format!("({:.4}, {:.4}, {:.4})", v.x, v.y, v.z)
}

impl fmt::Display for SceneSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "vertices   {}", thousands(self.vertices))?;
        write!(f, "triangles  {}", thousands(self.triangles))?;
        if self.degenerate_triangles > 0 {
            write!(f, " ({} degenerate)", thousands(self.degenerate_triangles))?;
        }
        writeln!(f)?;
        if self.instances > 0 {
            writeln!(
                f,
                "instanced  {} triangles ({} instances of {} mesh{} stored once)",
                thousands(self.instanced_triangles as usize),
                thousands(self.instances),
                thousands(self.meshes),
                if self.meshes == 1 { "" } else { "es" }
            )?;
        }
        writeln!(f, "spheres    {}", thousands(self.spheres))?;
        writeln!(f, "lights     {}", thousands(self.lights))?;
        writeln!(f, "materials  {}", thousands(self.materials.len()))?;
        for m in &self.materials {
            writeln!(
                f,
                "  {:<24} {} triangles, {} spheres",
                m.name,
                thousands(m.triangles),
                thousands(m.spheres)
            )?;
        }
        if self.bounds.is_empty() {
            writeln!(f, "bounds     empty")?;
        } else {
            writeln!(
                f,
                "bounds     min {} max {} size {}",
                vector(self.bounds.min),
                vector(self.bounds.max),
                vector(self.bounds.max - self.bounds.min)
            )?;
        }
        let m = &self.memory;
        writeln!(f, "memory     {} while rendering:", mib(m.render_total()))?;
        writeln!(
            f,
            "  shapes {}, shading {}, vertex normals {}",
            mib(m.shapes),
            mib(m.shading),
            mib(m.vertex_normals)
        )?;
        writeln!(f, "  BVH ~{}, film {}", mib(m.bvh), mib(m.film))?;
        writeln!(
            f,
            "  plus {} for the description while loading",
            mib(m.description)
        )?;
        for w in crate::warnings::coalesce(&self.warnings) {
            writeln!(f, "warning: {w}")?;
        }
        Ok(())
    }
}
