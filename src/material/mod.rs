//! Materials as the readers describe them: SPEC's Phong record, which full mode
//! shades, with its texture maps, and optionally a physically based material
//! ([`pbr`]) that path mode scatters by instead.

mod light;
pub mod pbr;

pub use light::{Incident, Light, LightKind};

use crate::math::{Float, Vec2, Vec3};
use crate::textures::{Encoding, TextureMap};
use pbr::{PbrMaps, PbrMaterial, PbrValues};

/// Index of a material in [`crate::Scene::materials`] (and in the description's list).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct MaterialId(pub u32);

/// A material of SPEC's lighting model. Defaults are those of an MTL `newmtl` with no
/// further lines: black, `Ns 1`, `Ni 1`, `d 1`, `al 1 0 0`.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// The name given by `newmtl`.
    pub name: String,
    /// `Ka`: ambient colour, added as is.
    pub ambient: Vec3,
    /// `Kd`: diffuse reflectance.
    pub diffuse: Vec3,
    /// `Ks`: specular reflectance.
    pub specular: Vec3,
    /// `Ke`: emission, added exactly like `Ka`.
    pub emission: Vec3,
    /// `Ns`: Phong exponent.
    pub shininess: Float,
    /// `Ni`: index of refraction.
    pub ior: Float,
    /// `d` (or `1 - Tr`): opacity. Read and kept, but not used by the default
    /// renderer: the reference images weight refraction by `al2` alone.
    pub opacity: Float,
    /// `al`: weights of local shading, reflection and refraction.
    pub albedo: [Float; 3],
    /// Texture maps, if any (boxed: most materials have none, and a material with
    /// none stays small and is told apart by one pointer test).
    pub maps: Option<Box<MaterialMaps>>,
    /// The physically based material this one is (glTF, MTL's `Pr`/`Pm`, TOML's
    /// `base_color`, ...), which path mode scatters by; `None` for SPEC's Phong
    /// materials. When set, the Phong fields hold its approximation for full mode
    /// ([`PbrValues::phong`]), and its maps are in [`MaterialMaps::pbr`].
    pub pbr: Option<Box<PbrMaterial>>,
}

/// A material's texture maps. Each colour map multiplies its colour (`map_Kd`
/// multiplies `Kd`); `map_Ns` multiplies `Ns`.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct MaterialMaps {
    /// `map_Ka`.
    pub ambient: Option<TextureMap>,
    /// `map_Kd` (glTF: the base colour texture).
    pub diffuse: Option<TextureMap>,
    /// `map_Ks`.
    pub specular: Option<TextureMap>,
    /// `map_Ke` (glTF: the emissive texture).
    pub emission: Option<TextureMap>,
    /// `map_Ns`: a scalar map.
    pub shininess: Option<TextureMap>,
    /// `map_d` or glTF's alpha mask: where the surface is cut out.
    pub cutout: Option<Cutout>,
    /// `bump`/`map_Bump`: a height map (a scalar map), which tilts the shading
    /// normal by its slope (see [`MaterialMaps::tangent_normal`]). Ignored when
    /// there is a normal map.
    pub bump: Option<TextureMap>,
    /// `norm`, a `bump` image that is a normal map, or glTF's normal texture: a
    /// tangent-space normal map (OpenGL's convention, as glTF's: red along `u`, green
    /// along `v`, blue out of the surface), linear. Its `-bm` (glTF's `scale`)
    /// multiplies the normal's x and y before it is normalised.
    pub normal: Option<TextureMap>,
    /// The maps of the physically based material ([`Material::pbr`]).
    pub pbr: PbrMaps,
    /// Whether the hit's interpolated vertex colour multiplies the diffuse colour
    /// (a physically based material's base colour), as glTF's `COLOR_0` does: set by
    /// [`crate::Scene::build`] on the materials of coloured triangles, so that
    /// materials without maps or colours keep their one-branch path.
    pub vertex_colours: bool,
}

/// Where a surface is cut out: rays pass through it where its alpha is below
/// `cutoff`, or, for a blended surface (glTF's `alphaMode: BLEND`), a fraction
/// `1 - alpha` of the rays that meet it pass, as stochastic transparency.
#[derive(Clone, Debug, PartialEq)]
pub struct Cutout {
    /// The alpha map (`map_d`, or glTF's base colour texture's alpha); none means
    /// alpha is `factor` everywhere.
    pub map: Option<TextureMap>,
    /// Multiplies the map's alpha (glTF's base colour factor's alpha; 1 for MTL).
    pub factor: Float,
    /// Alpha below this is cut out: 0.5 for MTL, glTF's `alphaCutoff`. Not read when
    /// `blend`.
    pub cutoff: Float,
    /// Blended (glTF's `BLEND`): the surface stops a ray with probability alpha,
    /// decided by [`Cutout::ray_key`] and the primitive, so that the same ray
    /// meeting the same triangle decides the same way in every query (closest hit,
    /// shadow ray, full and path mode alike) and different rays decide independently.
    pub blend: bool,
}

/// How a query treats a blended surface (glTF's `BLEND`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlendRule {
    /// Stochastic transparency: the surface stops the ray of this key
    /// ([`Cutout::ray_key`]) with probability alpha (path mode, and every query of a
    /// scene that does not blend in layers).
    Stochastic(u64),
    /// A closest-hit query of a scene that blends in layers (full mode): the surface
    /// is there wherever its alpha is above 0, and shading composites it over what
    /// lies behind it, as a rasterizer blends it.
    Layer,
    /// A shadow ray of a scene that blends in layers: the surface casts a shadow
    /// where its alpha is at least [`LAYER_SHADOW_ALPHA`], so that a pane of glass
    /// does not darken a room while a half-opaque bag shades the floor, without the
    /// dither a stochastic decision makes at one ray a pixel.
    Shadow,
}

/// The alpha from which a blended surface casts a shadow in a scene that blends in
/// layers ([`BlendRule::Shadow`]): the middle, where the expected transmittance
/// `1 - alpha` rounds to none.
pub const LAYER_SHADOW_ALPHA: Float = 0.5;

impl Cutout {
    /// The alpha at texture coordinates `uv`.
    #[inline]
    pub fn alpha(&self, uv: Vec2) -> Float {
        match &self.map {
            Some(map) => self.factor * map.scalar(uv, true),
            None => self.factor,
        }
    }

    /// Whether the surface is there at texture coordinates `uv` for a query that
    /// treats blended surfaces by `rule`, meeting primitive `prim` (only a blended
    /// surface reads them).
    #[inline]
    pub fn keeps(&self, uv: Vec2, rule: BlendRule, prim: u32) -> bool {
        let alpha = self.alpha(uv);
        if !self.blend {
            return alpha >= self.cutoff;
        }
        match rule {
            BlendRule::Stochastic(ray) => Cutout::uniform(ray, prim) < alpha,
            BlendRule::Layer => alpha > 0.0,
            BlendRule::Shadow => alpha >= LAYER_SHADOW_ALPHA,
        }
    }

    /// The part of the surface at `uv` that is there, on average over rays: alpha
    /// for a blended surface, 0 or 1 for a cut out one (what an emitter's light
    /// sample is weighted by).
    #[inline]
    pub fn coverage(&self, uv: Vec2) -> Float {
        let alpha = self.alpha(uv);
        if self.blend {
            alpha.clamp(0.0, 1.0)
        } else if alpha >= self.cutoff {
            1.0
        } else {
            0.0
        }
    }

    /// A key hashed from the bits of a ray's origin and direction, computed once per
    /// query: a blended surface's decisions are a deterministic function of the ray,
    /// with no random number to thread through traversal.
    #[inline]
    pub fn ray_key(origin: Vec3, dir: Vec3) -> u64 {
        let words = [
            origin.x.to_bits() as u64 | (origin.y.to_bits() as u64) << 32,
            origin.z.to_bits() as u64 | (dir.x.to_bits() as u64) << 32,
            dir.y.to_bits() as u64 | (dir.z.to_bits() as u64) << 32,
        ];
        words
            .iter()
            .fold(0x9E37_79B9_7F4A_7C15, |h, &w| mix64(h ^ w))
    }

    /// A number in [0, 1) for the ray of key `ray` meeting primitive `prim`,
    /// uniformly distributed over rays.
    #[inline]
    pub fn uniform(ray: u64, prim: u32) -> Float {
        let h = mix64(ray ^ (prim as u64 + 1).wrapping_mul(0xD6E8_FEB8_6659_FD93));
        (h >> 40) as Float * (1.0 / (1u64 << 24) as Float)
    }
}

/// The finaliser of SplitMix64 (Steele et al. 2014): every input bit flips each
/// output bit with probability about one half.
#[inline]
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A material's colours at one point of a surface: its constants, times its maps
/// there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceValues {
    /// `Ka`.
    pub ambient: Vec3,
    /// `Kd`.
    pub diffuse: Vec3,
    /// `Ks`.
    pub specular: Vec3,
    /// `Ke`.
    pub emission: Vec3,
    /// `Ns`.
    pub shininess: Float,
}

/// The colours Phong shading reads at a point: an untextured [`Material`]'s
/// constants, or a textured one's [`SurfaceValues`] there. Shading written over this
/// trait reads an untextured material's fields in place, as it did before textures,
/// instead of copying them into a [`SurfaceValues`] at every hit.
pub trait Colours {
    /// `Ka`.
    fn ambient(&self) -> Vec3;
    /// `Kd`.
    fn diffuse(&self) -> Vec3;
    /// `Ks`.
    fn specular(&self) -> Vec3;
    /// `Ke`.
    fn emission(&self) -> Vec3;
    /// `Ns`.
    fn shininess(&self) -> Float;
}

/// `Colours` read from the fields of the same names, which [`Material`] (its
/// constants, whatever the maps: for materials without maps) and [`SurfaceValues`]
/// both have.
macro_rules! colours_from_fields {
    ($($kind:ty),*) => {$(
        impl Colours for $kind {
            #[inline(always)]
            fn ambient(&self) -> Vec3 {
                self.ambient
            }
            #[inline(always)]
            fn diffuse(&self) -> Vec3 {
                self.diffuse
            }
            #[inline(always)]
            fn specular(&self) -> Vec3 {
                self.specular
            }
            #[inline(always)]
            fn emission(&self) -> Vec3 {
                self.emission
            }
            #[inline(always)]
            fn shininess(&self) -> Float {
                self.shininess
            }
        }
    )*};
}

colours_from_fields!(Material, SurfaceValues);

impl Material {
    /// A material with MTL defaults and the given name.
    pub fn named(name: impl Into<String>) -> Material {
        Material {
            name: name.into(),
            ambient: Vec3::ZERO,
            diffuse: Vec3::ZERO,
            specular: Vec3::ZERO,
            emission: Vec3::ZERO,
            shininess: 1.0,
            ior: 1.0,
            opacity: 1.0,
            albedo: [1.0, 0.0, 0.0],
            maps: None,
            pbr: None,
        }
    }

    /// A physically based material named `name`, its maps (`None` when it has none)
    /// and its Phong approximation for full mode; `emission` is its emitted radiance
    /// (its `Ke`).
    pub fn physically_based(
        name: impl Into<String>,
        pbr: PbrMaterial,
        emission: Vec3,
        maps: Option<Box<MaterialMaps>>,
    ) -> Material {
        let mut material = Material {
            emission,
            ior: pbr.ior,
            maps,
            ..Material::named(name)
        };
        let mut values = material.at_constants();
        pbr.constants().phong(&mut values);
        material.diffuse = values.diffuse;
        material.specular = values.specular;
        material.shininess = values.shininess;
        material.pbr = Some(Box::new(pbr));
        material
    }

    fn at_constants(&self) -> SurfaceValues {
        SurfaceValues {
            ambient: self.ambient,
            diffuse: self.diffuse,
            specular: self.specular,
            emission: self.emission,
            shininess: self.shininess,
        }
    }

    /// The physically based material's values at `uv`, if this is one.
    #[inline]
    pub fn pbr_at(&self, uv: Vec2) -> Option<PbrValues> {
        self.pbr_at_point(uv, Vec3::ONE)
    }

    /// [`Material::pbr_at`] where the vertex colour is `colour` (a hit's
    /// [`crate::Hit::colour`]): it multiplies the base colour if the material takes
    /// vertex colours ([`MaterialMaps::vertex_colours`]).
    #[inline]
    pub fn pbr_at_point(&self, uv: Vec2, colour: Vec3) -> Option<PbrValues> {
        let pbr = self.pbr.as_deref()?;
        let maps = self.maps.as_deref();
        let mut values = pbr.at(uv, maps.map(|m| &m.pbr));
        if maps.is_some_and(|m| m.vertex_colours) {
            values.base_color *= colour;
        }
        Some(values)
    }

    /// Whether this is an unlit physically based material (`KHR_materials_unlit`,
    /// [`PbrMaterial::unlit`]).
    #[inline]
    pub fn is_unlit(&self) -> bool {
        self.pbr.as_deref().is_some_and(|pbr| pbr.unlit)
    }

    /// The colour an unlit material ([`Material::is_unlit`]) shows at texture
    /// coordinates `uv` where the vertex colour is `colour`: its base colour there
    /// (factor, map and vertex colour, linear); `None` for any other material.
    #[inline]
    pub fn unlit_colour(&self, uv: Vec2, colour: Vec3) -> Option<Vec3> {
        if !self.is_unlit() {
            return None;
        }
        self.pbr_at_point(uv, colour)
            .map(|values| values.base_color)
    }

    /// The material's values at texture coordinates `uv`: the constants, each
    /// multiplied by its map's filtered value there (colour maps decoded from sRGB).
    /// Without maps, the constants exactly.
    #[inline]
    pub fn at(&self, uv: Vec2) -> SurfaceValues {
        self.at_point(uv, Vec3::ONE)
    }

    /// [`Material::at`] where the vertex colour is `colour` (a hit's
    /// [`crate::Hit::colour`]): it multiplies the diffuse colour (a physically based
    /// material's base colour, before its Phong approximation) if the material takes
    /// vertex colours ([`MaterialMaps::vertex_colours`]).
    #[inline]
    pub fn at_point(&self, uv: Vec2, colour: Vec3) -> SurfaceValues {
        let mut values = self.at_constants();
        if let Some(maps) = &self.maps {
            maps.apply(uv, colour, &mut values, self.pbr.as_deref());
        }
        values
    }

    /// Whether hits on the material read texture coordinates: it has maps, or it is
    /// anisotropic (its tangents come from them). The readers and the scene keep
    /// texture coordinates only when some material does.
    #[inline]
    pub fn needs_texcoords(&self) -> bool {
        self.maps.is_some() || self.pbr.as_deref().is_some_and(PbrMaterial::is_anisotropic)
    }

    /// Whether hits on the material read a tangent frame: it has a normal, bump or
    /// clearcoat normal map, or it is anisotropic. The scene keeps vertex tangents
    /// only for triangles of such materials.
    #[inline]
    pub fn needs_tangents(&self) -> bool {
        self.maps
            .as_deref()
            .is_some_and(MaterialMaps::perturbs_normals)
            || self.pbr.as_deref().is_some_and(PbrMaterial::is_anisotropic)
    }

    /// Whether some of the surface may be cut out (`map_d`, glTF's alpha mask).
    #[inline]
    pub fn cutout(&self) -> Option<&Cutout> {
        self.maps.as_ref()?.cutout.as_ref()
    }
}

impl MaterialMaps {
    /// Multiplies `values` by the maps at `uv`; for a physically based material
    /// (`pbr`), sets its Phong approximation from its values there. Out of line: only
    /// textured materials get here.
    #[inline(never)]
    fn apply(&self, uv: Vec2, vertex: Vec3, values: &mut SurfaceValues, pbr: Option<&PbrMaterial>) {
        let vertex = if self.vertex_colours {
            vertex
        } else {
            Vec3::ONE
        };
        if let Some(pbr) = pbr {
            let mut at = pbr.at(uv, Some(&self.pbr));
            at.base_color *= vertex;
            at.phong(values);
        } else {
            values.diffuse *= vertex;
        }
        let colour = |map: &Option<TextureMap>, value: &mut Vec3| {
            if let Some(map) = map {
                *value *= map.colour(uv, Encoding::Srgb);
            }
        };
        colour(&self.ambient, &mut values.ambient);
        colour(&self.diffuse, &mut values.diffuse);
        colour(&self.specular, &mut values.specular);
        colour(&self.emission, &mut values.emission);
        if let Some(map) = &self.shininess {
            values.shininess = (values.shininess * map.scalar(uv, false)).max(0.0);
        }
    }

    /// Whether the maps change the shading normal (a bump or normal map).
    #[inline]
    pub fn perturbs_normals(&self) -> bool {
        self.normal.is_some() || self.bump.is_some() || self.pbr.clearcoat_normal.is_some()
    }

    /// The unit clearcoat normal at `uv` in tangent space, from
    /// `clearcoatNormalTexture` (with its `scale`); `None` without one, when the coat
    /// takes the unperturbed shading normal (not the base's normal map), as
    /// `KHR_materials_clearcoat` says.
    pub fn coat_tangent_normal(&self, uv: Vec2) -> Option<Vec3> {
        self.pbr
            .clearcoat_normal
            .as_ref()
            .and_then(|map| normal_map_at(map, uv))
    }

    /// The unit shading normal at `uv` in tangent space (x along `u`, y along `v`,
    /// z the unperturbed normal), from the normal map if there is one, else from the
    /// bump map; `None` when neither gives one.
    ///
    /// A bump map's heights (0 to 1 after `-mm`) are read as heights in texels times
    /// `-bm`: the normal tilts by the height's slope per texel, measured by central
    /// differences one texel either side, the way height-to-normal-map tools convert
    /// them. (MTL gives heights no unit; tying them to world units would make the same
    /// map flat on a large model and spiky on a small one.)
    pub fn tangent_normal(&self, uv: Vec2) -> Option<Vec3> {
        if let Some(map) = &self.normal {
            return normal_map_at(map, uv);
        }
        let map = self.bump.as_ref()?;
        let (width, height) = map.texture.size();
        let scale = map.options.scale;
        // One texel, in the coordinates before `-s` scales them.
        let du = 1.0 / (width as Float * scale.x.abs().max(Float::MIN_POSITIVE));
        let dv = 1.0 / (height as Float * scale.y.abs().max(Float::MIN_POSITIVE));
        let h = |du: Float, dv: Float| map.scalar(uv + Vec2::new(du, dv), false);
        let slope_u = (h(du, 0.0) - h(-du, 0.0)) * 0.5;
        let slope_v = (h(0.0, dv) - h(0.0, -dv)) * 0.5;
        let bm = map.options.bump_multiplier;
        crate::math::try_unit(Vec3::new(-bm * slope_u, -bm * slope_v, 1.0))
    }

    /// Whether no map is set.
    pub fn is_empty(&self) -> bool {
        *self == MaterialMaps::default()
    }
}

/// The unit tangent-space normal a normal map gives at `uv`. Its `-bm` (glTF's
/// normal texture `scale`, Blender's normal map strength) scales the tilt: x and y,
/// as glTF says. The tilt is in the image's own axes, which a texture transform
/// turns or mirrors against the surface's tangent frame: it is turned back with
/// them ([`crate::textures::TextureOptions::image_to_surface`]), as the glTF sample
/// renderer does since it fixed `NormalTextureRotation`, so that turning a normal
/// map's transform renders as turning its texture coordinates would.
fn normal_map_at(map: &TextureMap, uv: Vec2) -> Option<Vec3> {
    let n = map.colour(uv, Encoding::Linear) * 2.0 - Vec3::ONE;
    let scale = map.options.bump_multiplier;
    let tilt = map.options.image_to_surface(Vec2::new(n.x, n.y)) * scale;
    crate::math::try_unit(Vec3::new(tilt.x, tilt.y, n.z))
}

impl Material {
    /// What faces get when no (known) material was named: a matte light grey, so that
    /// a scene without an MTL file still shows its shapes.
    pub fn fallback() -> Material {
        Material {
            diffuse: Vec3::splat(0.8),
            ..Material::named("default")
        }
    }
}
