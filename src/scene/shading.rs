//! The second phase of a hit: point, normals, texture coordinates and bumps of the
//! closest primitive found, and the alpha test cutouts make.

use super::*;

impl Scene {
    /// Whether primitive `prim` (a triangle) is there at barycentrics `u`, `v` for
    /// a query that treats blended surfaces by `rule` ([`Scene::blend_rule`]): not
    /// cut out by its material's alpha.
    #[inline]
    pub(super) fn keeps(&self, prim: u32, u: Float, v: Float, rule: BlendRule) -> bool {
        if !self.has_cutouts {
            return true;
        }
        let material = &self.materials[self.shading.get(prim).material.0 as usize];
        match material.cutout() {
            Some(cutout) => cutout.keeps(self.uv_at(prim, u, v), rule, prim),
            None => true,
        }
    }

    /// The texture coordinates of triangle `prim` at barycentrics `u`, `v`; zero
    /// when it has none.
    #[inline]
    pub(super) fn uv_at(&self, prim: u32, u: Float, v: Float) -> Vec2 {
        match self.prim_texcoords.get(prim as usize) {
            None | Some([NO_TEXCOORDS, ..]) => Vec2::ZERO,
            Some(ids) => {
                let [t0, t1, t2] = ids.map(|i| self.texcoords[i as usize]);
                t0 * (1.0 - u - v) + t1 * u + t2 * v
            }
        }
    }

    /// The vertex colour of primitive `prim` at barycentrics `u`, `v`; white when
    /// it has none.
    #[inline]
    fn colour_at(&self, prim: u32, u: Float, v: Float) -> Vec3 {
        match self.prim_colours.get(prim as usize) {
            None | Some([NO_COLOURS, ..]) => Vec3::ONE,
            Some(ids) => {
                let [c0, c1, c2] = ids.map(|i| self.colours[i as usize]);
                c0 * (1.0 - u - v) + c1 * u + c2 * v
            }
        }
    }

    /// The shading normal `ns` tilted by `material`'s bump or normal map at `uv`,
    /// and by its clearcoat normal map, in the tangent frame `frame` gives (tangent
    /// and bitangent, orthonormal about `ns`: [`Scene::tangents`]); `None` without
    /// such a map or a frame.
    #[inline]
    pub(super) fn perturbed_normals(
        &self,
        material: MaterialId,
        uv: Vec2,
        ns: Vec3,
        frame: impl FnOnce() -> Option<(Vec3, Vec3)>,
    ) -> (Option<Vec3>, Option<Vec3>) {
        let Some(maps) = self
            .materials
            .get(material.0 as usize)
            .and_then(|m| m.maps.as_deref())
            .filter(|maps| maps.perturbs_normals())
        else {
            return (None, None);
        };
        let Some((tangent, bitangent)) = frame() else {
            return (None, None);
        };
        let tilt = |local: Vec3| try_unit(tangent * local.x + bitangent * local.y + ns * local.z);
        (
            maps.tangent_normal(uv).and_then(tilt),
            maps.coat_tangent_normal(uv).and_then(tilt),
        )
    }

    /// The direction of anisotropy of an anisotropic `material` at `uv` in the
    /// tangent frame `frame` gives; `None` for other materials or without a frame.
    #[inline]
    pub(super) fn anisotropy_tangent(
        &self,
        material: MaterialId,
        uv: Vec2,
        frame: impl FnOnce() -> Option<(Vec3, Vec3)>,
    ) -> Option<Vec3> {
        let material = self.materials.get(material.0 as usize)?;
        let pbr = material.pbr.as_deref().filter(|pbr| pbr.is_anisotropic())?;
        let (tangent, bitangent) = frame()?;
        let maps = material.maps.as_deref();
        let direction = pbr.anisotropy_direction(uv, maps.map(|m| &m.pbr));
        Some(tangent * direction.x + bitangent * direction.y)
    }

    /// The unit tangent and bitangent of triangle `prim` at barycentrics `hit` about
    /// the unit shading normal `ns`: its vertex tangents interpolated
    /// ([`Scene::vertex_frame`]), else (a mesh without them, or where they give no
    /// direction) the triangle's own along its texture coordinates
    /// ([`Scene::uv_tangents`]).
    #[inline]
    fn tangents(
        &self,
        prim: u32,
        triangle: &Triangle,
        ns: Vec3,
        hit: &PrimHit,
    ) -> Option<(Vec3, Vec3)> {
        self.vertex_frame(prim, ns, hit, |t| t, false)
            .or_else(|| self.uv_tangents(prim, triangle, ns))
    }

    /// Whether primitive `prim` has vertex tangents.
    #[inline]
    pub(super) fn has_vertex_tangents(&self, prim: u32) -> bool {
        (self.prim_tangents.get(prim as usize)).is_some_and(|ids| ids[0] != tangents::NO_TANGENTS)
    }

    /// The tangent frame of triangle `prim`'s vertex tangents at barycentrics `hit`
    /// about the unit shading normal `ns`, as the glTF sample viewer and three.js
    /// make it: each corner's tangent moved by `place` (an instance's linear part),
    /// interpolated, made orthogonal to `ns` (Gram-Schmidt), and the bitangent
    /// `sign * cross(ns, tangent)`, the sign turned where `mirrored` (a placement
    /// that mirrors). `None` without vertex tangents, or where the interpolated
    /// tangent has no direction across `ns`.
    #[inline]
    pub(super) fn vertex_frame(
        &self,
        prim: u32,
        ns: Vec3,
        hit: &PrimHit,
        place: impl Fn(Vec3) -> Vec3,
        mirrored: bool,
    ) -> Option<(Vec3, Vec3)> {
        let ids = *self.prim_tangents.get(prim as usize)?;
        if ids[0] == tangents::NO_TANGENTS {
            return None;
        }
        let weights = [1.0 - hit.u - hit.v, hit.u, hit.v];
        let (mut tangent, mut sign) = (Vec3::ZERO, 0.0);
        for k in 0..3 {
            let t = self.tangents[ids[k] as usize];
            tangent += try_unit(place(t.truncate())).unwrap_or(Vec3::ZERO) * weights[k];
            sign += t.w * weights[k];
        }
        let tangent = try_unit(tangent - ns * ns.dot(tangent))?;
        let bitangent = ns.cross(tangent);
        Some((
            tangent,
            if (sign < 0.0) != mirrored {
                -bitangent
            } else {
                bitangent
            },
        ))
    }

    /// The unit tangent and bitangent of triangle `prim` about the unit normal `ns`,
    /// along its texture coordinates' `u` and `v` (one frame for the whole
    /// triangle); `None` without texture coordinates or with a degenerate UV layout.
    #[inline]
    fn uv_tangents(&self, prim: u32, triangle: &Triangle, ns: Vec3) -> Option<(Vec3, Vec3)> {
        let ids = self.prim_texcoords.get(prim as usize)?;
        if ids[0] == NO_TEXCOORDS {
            return None;
        }
        let [t0, t1, t2] = ids.map(|i| self.texcoords[i as usize]);
        let (duv1, duv2) = (t1 - t0, t2 - t0);
        let det = duv1.x * duv2.y - duv1.y * duv2.x;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let dpdu = (triangle.e1 * duv2.y - triangle.e2 * duv1.y) / det;
        let dpdv = (triangle.e2 * duv1.x - triangle.e1 * duv2.x) / det;
        let tangent = try_unit(dpdu - ns * ns.dot(dpdu))?;
        let bitangent = ns.cross(tangent);
        // Mirrored texture layouts run `v` the other way round.
        let bitangent = if bitangent.dot(dpdv) < 0.0 {
            -bitangent
        } else {
            bitangent
        };
        Some((tangent, bitangent))
    }

    /// Second phase of a hit: point, normals and material, for the closest hit only
    /// (texture coordinates and bumps are added, in textured scenes only, by
    /// [`Scene::textured_hit_details`]).
    pub(super) fn hit_details(&self, ray: &Ray, packet: u32, lane: usize, hit: PrimHit) -> Hit {
        self.hit_details_inline(ray, packet, lane, hit)
    }

    /// [`Scene::hit_details`] inlined into the caller, which then builds the hit in
    /// place: returned from a call, the hit is stored in pieces and read back whole,
    /// which stalls the load (no store forwarding) in path mode's batches.
    #[inline(always)]
    pub(super) fn hit_details_inline(
        &self,
        ray: &Ray,
        packet: u32,
        lane: usize,
        hit: PrimHit,
    ) -> Hit {
        let packet = &self.packets[packet as usize];
        let (Some(prim), Some(shape)) = (packet.prim(lane), packet.shape(lane)) else {
            unreachable!("hits come from used lanes")
        };
        let shading = self.shading.get(prim);
        let (p, n, ns, lift) = match shape {
            Shape::Triangle(tri) => {
                // `build` kept only triangles whose normal `try_unit` accepts.
                let n = try_unit(tri.normal()).unwrap_or(-ray.dir);
                let p = ray.at(hit.t);
                // Kept only on the side the ray came from: vertex normals facing
                // away from it describe a surface behind the one it hit. (Full mode
                // reads it under the default rig only: SPEC starts every shadow ray
                // an epsilon off the triangle.) A scene without vertex normals
                // skips it whole: its arithmetic in the batches' hits cost the
                // Cornell box 1.03x-1.07x the CPU.
                let lift = match self.vertex_normals.is_empty() {
                    true => Vec3::ZERO,
                    false => Some(self.smooth_lift(shading, &tri, p, &hit))
                        .filter(|lift| lift.dot(ray.dir) < 0.0)
                        .unwrap_or(Vec3::ZERO),
                };
                (p, n, self.shading_normal(shading, n, &hit), lift)
            }
            Shape::Sphere(s) => {
                let p = ray.at(hit.t);
                let n = try_unit(p - s.center).unwrap_or(-ray.dir);
                (s.center + n * s.radius, n, n, Vec3::ZERO)
            }
        };
        let front = n.dot(ray.dir) <= 0.0;
        let face = |v: Vec3| if v.dot(ray.dir) > 0.0 { -v } else { v };
        Hit {
            t: hit.t,
            p,
            n: face(n),
            ns: face(ns),
            uv: Vec2::ZERO,
            coat_ns: Vec3::ZERO,
            tangent: Vec3::ZERO,
            lift,
            colour: Vec3::ONE,
            material: shading.material,
            front,
        }
    }

    /// [`Hit::lift`] at `p`, barycentric coordinates `hit` on `tri`: zero without
    /// vertex normals.
    #[inline(always)]
    fn smooth_lift(&self, shading: PrimShading, tri: &Triangle, p: Vec3, hit: &PrimHit) -> Vec3 {
        self.smooth_lift_with(shading, tri, p, hit, |v| v)
    }

    /// [`Scene::smooth_lift`] with each vertex normal first moved by `place` (an
    /// instance's placement, giving a unit vector or zero), `tri` and `p` placed
    /// already.
    #[inline(always)]
    pub(super) fn smooth_lift_with(
        &self,
        shading: PrimShading,
        tri: &Triangle,
        p: Vec3,
        hit: &PrimHit,
        place: impl Fn(Vec3) -> Vec3,
    ) -> Vec3 {
        match shading.normals {
            [NO_NORMALS, ..] => Vec3::ZERO,
            ids => {
                let corners = [tri.v0, tri.v0 + tri.e1, tri.v0 + tri.e2];
                let weights = [1.0 - hit.u - hit.v, hit.u, hit.v];
                let mut lift = Vec3::ZERO;
                for k in 0..3 {
                    let normal = place(self.vertex_normals[ids[k] as usize]);
                    let below = (p - corners[k]).dot(normal).min(0.0);
                    lift -= normal * (weights[k] * below);
                }
                if lift.is_finite() { lift } else { Vec3::ZERO }
            }
        }
    }

    /// The shading normal of a triangle hit: its interpolated vertex normals, or its
    /// unit geometric normal `n` (not turned to face the ray).
    #[inline(always)]
    pub(super) fn shading_normal(&self, shading: PrimShading, n: Vec3, hit: &PrimHit) -> Vec3 {
        self.shading_normal_with(shading, n, hit, |v| v)
    }

    /// [`Scene::shading_normal`] with each vertex normal first moved by `place` (an
    /// instance's placement; zero marks one without a direction).
    #[inline(always)]
    pub(super) fn shading_normal_with(
        &self,
        shading: PrimShading,
        n: Vec3,
        hit: &PrimHit,
        place: impl Fn(Vec3) -> Vec3,
    ) -> Vec3 {
        match shading.normals {
            [NO_NORMALS, ..] => n,
            ids => {
                let [n0, n1, n2] = ids.map(|i| match place(self.vertex_normals[i as usize]) {
                    Vec3::ZERO => n,
                    unit => unit,
                });
                let w = 1.0 - hit.u - hit.v;
                try_unit(n0 * w + n1 * hit.u + n2 * hit.v).unwrap_or(n)
            }
        }
    }

    /// [`Scene::hit_details`] in a textured or vertex-coloured scene: also the
    /// texture coordinates and vertex colour, if the primitive is a triangle whose
    /// material has maps (the only reader of `Hit::uv` and `Hit::colour`), and under a bump or normal map the tilted shading normal (turned to
    /// face the ray).
    #[inline(never)]
    pub(super) fn textured_hit_details(
        &self,
        ray: &Ray,
        packet: u32,
        lane: usize,
        hit: PrimHit,
    ) -> Hit {
        let mut details = self.hit_details(ray, packet, lane, hit);
        let packet = &self.packets[packet as usize];
        let (Some(prim), Some(Shape::Triangle(triangle))) = (packet.prim(lane), packet.shape(lane))
        else {
            return details;
        };
        let material = details.material;
        let reads_texcoords = self
            .materials
            .get(material.0 as usize)
            .is_some_and(Material::needs_texcoords);
        if !reads_texcoords {
            return details;
        }
        let uv = self.uv_at(prim, hit.u, hit.v);
        details.uv = uv;
        details.colour = self.colour_at(prim, hit.u, hit.v);
        // The shading normal before `hit_details` turned it.
        let n = try_unit(triangle.normal()).unwrap_or(-ray.dir);
        let ns = self.shading_normal(self.shading.get(prim), n, &hit);
        // Turned with the normal they perturb, so that a bump cannot turn the shading
        // normal to the other side at grazing angles.
        let turn = |v: Vec3| if ns.dot(ray.dir) > 0.0 { -v } else { v };
        let frame = || self.tangents(prim, &triangle, ns, &hit);
        let (bumped, coat) = self.perturbed_normals(material, uv, ns, frame);
        if let Some(bumped) = bumped {
            details.ns = turn(bumped);
            // A coat without a normal map of its own lies on the unperturbed surface.
            details.coat_ns = turn(ns);
        }
        if let Some(coat) = coat {
            details.coat_ns = turn(coat);
        }
        if let Some(tangent) = self.anisotropy_tangent(material, uv, frame) {
            details.tangent = tangent;
        }
        details
    }
}
