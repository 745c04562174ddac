//! Which object each primitive belongs to, for the `object_id` output: the
//! description's [`ObjectDesc`] runs of triangles and spheres, looked up by a
//! primitive's place in the description (a binary search, once per pixel, never in
//! traversal).

use super::{Hit, Scene};
use crate::description::ObjectDesc;
use crate::math::Ray;
use crate::shapes::PrimHit;

/// The objects of a scene, in the description's order, with where each begins.
#[derive(Clone, Debug, Default)]
pub struct Objects {
    names: Vec<String>,
    /// Each object's first triangle, non-decreasing.
    triangle_starts: Vec<u32>,
    /// Each object's first sphere, non-decreasing.
    sphere_starts: Vec<u32>,
    /// The description's triangle count: its sphere `i` has description index
    /// `triangles + i`.
    triangles: u32,
    /// The id of the first instance's object, in a scene with instances.
    first_placed: Option<u32>,
}

impl Objects {
    /// The objects of a description with `triangles` triangles and `spheres`
    /// spheres. Shapes before the first object (or all of them, when the readers
    /// named none) form an unnamed object, numbered 0.
    pub fn new(objects: Vec<ObjectDesc>, triangles: usize, spheres: usize) -> Objects {
        let mut table = Objects {
            triangles: triangles as u32,
            ..Objects::default()
        };
        let starts_at_zero = objects
            .first()
            .is_some_and(|o| o.first_triangle == 0 && o.first_sphere == 0);
        if !starts_at_zero && triangles + spheres > 0 {
            table.push(String::new(), 0, 0);
        }
        for object in objects {
            // A reader's starts only grow; clamped all the same, so that a lookup
            // never misses.
            let t = object
                .first_triangle
                .max(table.triangle_starts.last().copied().unwrap_or(0));
            let s = object
                .first_sphere
                .max(table.sphere_starts.last().copied().unwrap_or(0));
            table.push(object.name, t, s);
        }
        table
    }

    /// Where each object's triangles begin, in order.
    pub(super) fn triangle_starts(&self) -> &[u32] {
        &self.triangle_starts
    }

    /// Adds an object that holds none of the description's own shapes: an instance's
    /// copy, whose hits name it by [`Objects::placed_object`].
    pub fn push_after_shapes(&mut self, name: String) {
        if self.first_placed.is_none() {
            self.first_placed = Some(self.names.len() as u32);
        }
        self.push(name, u32::MAX, u32::MAX);
    }

    /// The id of instance `instance`'s object ([`Objects::push_after_shapes`]).
    pub fn placed_object(&self, instance: u32) -> u32 {
        self.first_placed.unwrap_or(self.names.len() as u32) + instance
    }

    fn push(&mut self, name: String, first_triangle: u32, first_sphere: u32) {
        self.names.push(name);
        self.triangle_starts.push(first_triangle);
        self.sphere_starts.push(first_sphere);
    }

    /// The object names, by id.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The id of the object holding the description's primitive `source` (its
    /// triangles, then its spheres, as [`Scene::source_index`] numbers them).
    pub fn of_source(&self, source: usize) -> u32 {
        let (starts, index) = match source.checked_sub(self.triangles as usize) {
            None => (&self.triangle_starts, source as u32),
            Some(sphere) => (&self.sphere_starts, sphere as u32),
        };
        starts
            .partition_point(|&start| start <= index)
            .saturating_sub(1) as u32
    }
}

impl Scene {
    /// The names of the scene's objects, by object id: a glTF node's name (or
    /// `node N`), a mesh file's name; `""` for the unnamed object of shapes outside
    /// any (see [`ObjectDesc`]).
    pub fn object_names(&self) -> &[String] {
        self.objects.names()
    }

    /// [`Scene::intersect`]'s hit, with the id of the object hit.
    pub fn intersect_object(&self, ray: &Ray) -> Option<(Hit, u32)> {
        if let Some(instances) = &self.instances {
            return self.intersect_object_instanced(instances, ray);
        }
        self.closest_lane(ray)
            .and_then(|found| self.object_hit(ray, found))
    }

    /// The hit of `ray` on the primitive in `lane` of `packet`, as
    /// [`Scene::intersect`] details it, with its object.
    pub(super) fn object_hit(
        &self,
        ray: &Ray,
        (packet, lane, found): (u32, usize, PrimHit),
    ) -> Option<(Hit, u32)> {
        let prim = self.packets[packet as usize].prim(lane)?;
        let hit = if !self.second_phase {
            self.hit_details(ray, packet, lane, found)
        } else {
            self.textured_hit_details(ray, packet, lane, found)
        };
        Some((hit, self.objects.of_source(self.source_index(prim))))
    }

    /// [`Scene::intersect_object`] of each of `rays` (at most
    /// [`crate::bvh::PACKET_SIZE`], coherent: a tile of camera rays) into `hits`,
    /// traced as one packet ([`Scene::intersect_packet`]), bit for bit the same.
    ///
    /// # Panics
    /// If `rays` is empty, longer than a packet, or not as long as `hits`.
    pub fn intersect_object_packet(&self, rays: &[Ray], hits: &mut [Option<(Hit, u32)>]) {
        assert_eq!(rays.len(), hits.len(), "one hit per ray");
        if self.instances.is_some() {
            for (hit, ray) in hits.iter_mut().zip(rays) {
                *hit = self.intersect_object(ray);
            }
            return;
        }
        let found = self.closest_lanes_packet(rays);
        for ((hit, ray), found) in hits.iter_mut().zip(rays).zip(found) {
            *hit = found.and_then(|found| self.object_hit(ray, found));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn object(name: &str, first_triangle: u32, first_sphere: u32) -> ObjectDesc {
        ObjectDesc {
            name: name.into(),
            first_triangle,
            first_sphere,
        }
    }

    #[test]
    fn primitives_belong_to_the_run_they_fall_in() {
        // Triangles 0..3 unnamed, 3..7 "a", 7..10 "b"; spheres 0..2 "a", 2.. "c".
        let objects = Objects::new(
            vec![object("a", 3, 0), object("b", 7, 2), object("c", 10, 2)],
            10,
            4,
        );
        assert_eq!(objects.names(), ["", "a", "b", "c"]);
        let ids: Vec<u32> = (0..14).map(|i| objects.of_source(i)).collect();
        assert_eq!(ids, [0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 1, 1, 3, 3]);
    }

    #[test]
    fn a_description_without_objects_is_one_unnamed_object() {
        let objects = Objects::new(Vec::new(), 5, 1);
        assert_eq!(objects.names(), [""]);
        assert!((0..6).all(|i| objects.of_source(i) == 0));
        assert!(Objects::new(Vec::new(), 0, 0).names().is_empty());
    }
}
