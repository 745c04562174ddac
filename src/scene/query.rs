//! Single-ray queries: the closest hit and any hit along one ray, with and without
//! cutouts, and the linear reference for tests.

use super::*;

impl Scene {
    /// The closest hit along `ray`, if any.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if let Some(instances) = &self.instances {
            return self.intersect_instanced(instances, ray);
        }
        let (packet, lane, hit) = self.closest_lane(ray)?;
        // Texture coordinates and bumps: in textured scenes only, out of line, so
        // that the hits of other scenes pay one predictable branch for them and are
        // written in place as before.
        if self.second_phase {
            return Some(self.textured_hit_details(ray, packet, lane, hit));
        }
        Some(self.hit_details(ray, packet, lane, hit))
    }

    /// The first phase of [`Scene::intersect`]: the closest primitive hit (its index
    /// in leaf order) with distance and barycentric coordinates, and no shading data.
    /// This is what ray-query libraries such as Embree return, so benchmarks compare
    /// against it. Inlined into its callers' loops (the array query's among them):
    /// 1.03x-1.05x on the 11k-triangle dragon's incoherent rays.
    #[inline(always)]
    pub fn intersect_primitive(&self, ray: &Ray) -> Option<(u32, PrimHit)> {
        if let Some(instances) = &self.instances {
            return self.intersect_primitive_instanced(instances, ray);
        }
        self.named(self.closest_lane(ray))
    }

    /// A closest hit as packet, lane and hit, with its primitive's index (leaf
    /// order) in place of packet and lane.
    #[inline(always)]
    pub(super) fn named(&self, found: Option<(u32, usize, PrimHit)>) -> Option<(u32, PrimHit)> {
        let (packet, lane, hit) = found?;
        Some((self.packets[packet as usize].prim(lane)?, hit))
    }

    /// The closest hit as the packet and lane that hold its primitive.
    #[inline(always)]
    pub(super) fn closest_lane(&self, ray: &Ray) -> Option<(u32, usize, PrimHit)> {
        self.closest_lane_within(ray, Float::INFINITY)
    }

    /// [`Scene::closest_lane`] among hits nearer than `t_max` (an instance's mesh is
    /// searched only up to the nearest hit found so far).
    #[inline(always)]
    pub(super) fn closest_lane_within(
        &self,
        ray: &Ray,
        t_max: Float,
    ) -> Option<(u32, usize, PrimHit)> {
        if self.has_cutouts {
            return self.closest_lane_with_cutouts(ray, t_max);
        }
        let query = RayQuery::new(ray);
        let lanes = PacketRay::new(ray);
        let mut closest = None;
        let mut t_max = t_max;
        self.wide.walk_ordered(
            &query,
            &mut t_max,
            &self.packets,
            #[inline(always)]
            |first, count, t_max| {
                self.nearest_in_leaf(&lanes, first, count, t_max, &mut closest);
                false
            },
        );
        closest
    }

    /// Tests the ray in `lanes` against packets `first..first + count`, in order, and
    /// records in `closest` (packet, lane and hit) any hit nearer than `t_max`, which
    /// it lowers: the leaf test of [`Scene::closest_lane`].
    #[inline(always)]
    pub(super) fn nearest_in_leaf(
        &self,
        lanes: &PacketRay,
        first: u32,
        count: u32,
        t_max: &mut Float,
        closest: &mut Option<(u32, usize, PrimHit)>,
    ) {
        let end = first + count;
        let mut index = first;
        while index < end {
            let packet = &self.packets[index as usize];
            // Two triangle packets in one eight-lane test, as most leaves of a mesh
            // are: the same hit as testing them in turn.
            if index + 1 < end
                && let next = &self.packets[index as usize + 1]
                && !packet.holds_spheres()
                && !next.holds_spheres()
            {
                if let Some((lane, hit)) =
                    TrianglePacket::intersect_pair(packet, next, lanes, *t_max)
                {
                    *t_max = hit.t;
                    *closest = Some((index + (lane / LANES) as u32, lane % LANES, hit));
                }
                index += 2;
                continue;
            }
            if let Some((lane, hit)) = packet.intersect_any_kind(lanes, *t_max) {
                *t_max = hit.t;
                *closest = Some((index, lane, hit));
            }
            index += 1;
        }
    }

    /// [`Scene::nearest_in_leaf`] for a walk that visits a ray's leaves in another
    /// order than its own walk, in a leaf whose box the ray entered at `entry`: also
    /// whether the ray's answer could depend on that order, as it can when a hit lies
    /// at exactly `t_max` (its own walk may have met it first) or a nearer one before
    /// `entry` (its own walk may have passed it by).
    #[inline(always)]
    pub(super) fn nearest_in_leaf_noting_order(
        &self,
        lanes: &PacketRay,
        first: u32,
        count: u32,
        entry: Float,
        t_max: &mut Float,
        closest: &mut Option<(u32, usize, PrimHit)>,
    ) -> bool {
        let mut order_matters = false;
        // A packet's nearest hit up to the next float after `t_max`: a hit at
        // exactly `t_max` is reported too.
        let mut note = |index: u32, lane: usize, hit: PrimHit, t_max: &mut Float| {
            if hit.t < *t_max {
                order_matters |= hit.t < entry;
                *t_max = hit.t;
                *closest = Some((index, lane, hit));
            } else {
                order_matters = true;
            }
        };
        let end = first + count;
        let mut index = first;
        while index < end {
            let packet = &self.packets[index as usize];
            if index + 1 < end
                && let next = &self.packets[index as usize + 1]
                && !packet.holds_spheres()
                && !next.holds_spheres()
            {
                // Both packets in one eight-lane test, then each one's nearest as
                // testing them in turn finds it: the second's only up to the
                // first's hit.
                let (valid, t, u, v) =
                    TrianglePacket::hits_pair(packet, next, lanes, t_max.next_up());
                let hit_at = |lane: usize| PrimHit {
                    t: t[lane],
                    u: u[lane],
                    v: v[lane],
                };
                if let Some(lane) = nearest_in_mask(valid & 0xf, &t) {
                    note(index, lane, hit_at(lane), t_max);
                }
                if let Some(lane) = nearest_in_mask(valid & 0xf0, &t)
                    && t[lane] <= *t_max
                {
                    note(index + 1, lane - LANES, hit_at(lane), t_max);
                }
                index += 2;
                continue;
            }
            if let Some((lane, hit)) = packet.intersect_any_kind(lanes, t_max.next_up()) {
                note(index, lane, hit, t_max);
            }
            index += 1;
        }
        order_matters
    }

    /// [`Scene::closest_lane`] for scenes with cutouts: a triangle hit counts only
    /// where its material keeps the surface, so within a packet the nearest kept lane
    /// wins. Out of line, so that the traversal of other scenes stays as it was.
    #[inline(never)]
    pub(super) fn closest_lane_with_cutouts(
        &self,
        ray: &Ray,
        t_max: Float,
    ) -> Option<(u32, usize, PrimHit)> {
        let query = RayQuery::new(ray);
        let lanes = PacketRay::new(ray);
        let rule = self.blend_rule(ray, BlendQuery::Closest);
        let mut closest = None;
        let mut t_max = t_max;
        self.wide
            .walk_ordered(&query, &mut t_max, &self.packets, |first, count, t_max| {
                for index in first..first + count {
                    let packet = &self.packets[index as usize];
                    let found = if packet.holds_spheres() {
                        packet.intersect_any_kind(&lanes, *t_max)
                    } else {
                        self.nearest_kept_lane(packet, &lanes, *t_max, rule)
                    };
                    if let Some((lane, hit)) = found {
                        *t_max = hit.t;
                        closest = Some((index, lane, hit));
                    }
                }
                false
            });
        closest
    }

    /// The nearest lane of a triangle packet hit within `t_max` whose surface is not
    /// cut out there (the lowest lane on equal distances, as `TrianglePacket::intersect`).
    #[inline]
    pub(super) fn nearest_kept_lane(
        &self,
        packet: &TrianglePacket,
        lanes: &PacketRay,
        t_max: Float,
        rule: BlendRule,
    ) -> Option<(usize, PrimHit)> {
        let (mut mask, t, u, v) = packet.hits(lanes, t_max);
        while let Some(best) = nearest_in_mask(mask, &t) {
            let hit = PrimHit {
                t: t[best],
                u: u[best],
                v: v[best],
            };
            match packet.prim(best) {
                Some(prim) if self.keeps(prim, hit.u, hit.v, rule) => return Some((best, hit)),
                _ => mask &= !(1 << best),
            }
        }
        None
    }

    /// Whether anything blocks `ray` before distance `t_max`.
    #[inline]
    pub fn occluded(&self, ray: &Ray, t_max: Float) -> bool {
        self.occluded_inlined(ray, t_max)
    }

    /// [`Scene::occluded`], inlined into loops over rays (the array query's).
    #[inline(always)]
    pub(super) fn occluded_inlined(&self, ray: &Ray, t_max: Float) -> bool {
        if let Some(instances) = &self.instances {
            return self.occluded_instanced(instances, ray, t_max);
        }
        self.occluded_level(ray, t_max)
    }

    /// [`Scene::occluded`] on this level's own primitives (not its instances').
    #[inline(always)]
    pub(super) fn occluded_level(&self, ray: &Ray, t_max: Float) -> bool {
        self.occluded_level_query(ray, &RayQuery::new(ray), t_max)
    }

    /// [`Scene::occluded_level`] with the ray's `query` made by the caller (a scene
    /// with instances walks its top level with the same one).
    #[inline(always)]
    pub(super) fn occluded_level_query(&self, ray: &Ray, query: &RayQuery, t_max: Float) -> bool {
        if self.has_cutouts {
            return self.occluded_with_cutouts(ray, t_max);
        }
        let lanes = PacketRay::new(ray);
        let mut t_max = t_max;
        self.wide
            .walk_any(query, &mut t_max, &self.packets, |first, count, t_max| {
                self.blocker_in_leaf(&lanes, first, count, *t_max)
            })
    }

    /// Whether some primitive of packets `first..first + count` blocks the ray in
    /// `lanes` before `t_max`: the leaf test of [`Scene::occluded`].
    #[inline(always)]
    pub(super) fn blocker_in_leaf(
        &self,
        lanes: &PacketRay,
        first: u32,
        count: u32,
        t_max: Float,
    ) -> bool {
        let mut packets = &self.packets[first as usize..(first + count) as usize];
        loop {
            match packets {
                // Two triangle packets in one eight-lane test.
                [a, b, rest @ ..] if !a.holds_spheres() && !b.holds_spheres() => {
                    if TrianglePacket::hits_pair(a, b, lanes, t_max).0 != 0 {
                        return true;
                    }
                    packets = rest;
                }
                [a, rest @ ..] => {
                    if a.occludes_any_kind(lanes, t_max) {
                        return true;
                    }
                    packets = rest;
                }
                [] => return false,
            }
        }
    }

    /// [`Scene::occluded`] for scenes with cutouts: a lane blocks the ray only where
    /// its surface is kept.
    #[inline(never)]
    pub(super) fn occluded_with_cutouts(&self, ray: &Ray, t_max: Float) -> bool {
        let query = RayQuery::new(ray);
        let lanes = PacketRay::new(ray);
        let rule = self.blend_rule(ray, BlendQuery::Shadow);
        let mut t_max = t_max;
        self.wide
            .walk_any(&query, &mut t_max, &self.packets, |first, count, t_max| {
                self.packets[first as usize..(first + count) as usize]
                    .iter()
                    .any(|packet| {
                        if packet.holds_spheres() {
                            return packet.occludes_any_kind(&lanes, *t_max);
                        }
                        let (mut mask, _, u, v) = packet.hits(&lanes, *t_max);
                        while mask != 0 {
                            let lane = mask.trailing_zeros() as usize;
                            mask &= mask - 1;
                            if packet
                                .prim(lane)
                                .is_some_and(|prim| self.keeps(prim, u[lane], v[lane], rule))
                            {
                                return true;
                            }
                        }
                        false
                    })
            })
    }

    /// The closest hit by testing every primitive with the scalar kernels: the slow
    /// reference for tests.
    pub fn intersect_linear(&self, ray: &Ray) -> Option<Hit> {
        let rule = self.blend_rule(ray, BlendQuery::Closest);
        let mut closest = None;
        let mut t_max = Float::INFINITY;
        for (index, packet) in self.packets.iter().enumerate() {
            for lane in 0..LANES {
                let Some(shape) = packet.shape(lane) else {
                    continue;
                };
                if let Some(hit) = shape.intersect(ray, t_max)
                    && (matches!(shape, Shape::Sphere(_))
                        || packet
                            .prim(lane)
                            .is_some_and(|p| self.keeps(p, hit.u, hit.v, rule)))
                {
                    t_max = hit.t;
                    closest = Some((index as u32, lane, hit));
                }
            }
        }
        closest.map(|(packet, lane, hit)| {
            if !self.second_phase {
                self.hit_details(ray, packet, lane, hit)
            } else {
                self.textured_hit_details(ray, packet, lane, hit)
            }
        })
    }
}
