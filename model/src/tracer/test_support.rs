//! What several of the tracer's tests use: a deterministic generator, and the triangle pairs of the
//! standard workloads as the classification meets them.

use super::arith::{affine, v3, BoundedF64};
use super::band::{triangle_band, vertex_static_radius, InstanceBand, TriangleBand};
use super::outside::{pre_test, PreTest};
use super::prepare::{PreparedScene, RayF64};
use super::triangle::{triangle_signs, TriangleSigns, TriangleValues};
use super::PrimitiveKind;
use crate::scene::{GeometryData, Ray, Transform3x4};

/// A deterministic generator (64-bit LCG, high bits).
pub(crate) struct Lcg(pub(crate) u64);

impl Lcg {
    /// Uniform in [0, 1).
    pub(crate) fn unit(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    pub(crate) fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// One of `xs`, uniformly.
    pub(crate) fn pick(&mut self, xs: &[f64]) -> f64 {
        xs[((self.unit() * xs.len() as f64) as usize).min(xs.len() - 1)]
    }
}

/// A (ray, triangle) pair of a standard workload, with what `classify_triangle` gives its
/// classification: the world vertices with their error bounds, their static radii, the instance's
/// band and the pair's band.
pub(crate) struct WorkloadPair<'a> {
    pub(crate) workload: &'static str,
    pub(crate) ray: &'a Ray,
    pub(crate) rf: &'a RayF64,
    pub(crate) world: [[BoundedF64; 3]; 3],
    pub(crate) radius: [f64; 3],
    pub(crate) instance_band: &'a InstanceBand,
    pub(crate) band: TriangleBand,
}

/// Calls `visit` with every triangle pair the walk keeps near a ray on the standard workloads
/// (12x12 camera rays each).
pub(crate) fn for_each_workload_pair(mut visit: impl FnMut(&WorkloadPair)) {
    for w in super::workload::standard_workloads(12, false) {
        let scene = PreparedScene::new(&w.scene).expect("a defined workload");
        for ray in &w.rays {
            let rf = RayF64::of(ray);
            let mut near = Vec::new();
            let cut = std::cell::Cell::new(f64::INFINITY);
            scene.for_each_near(&rf, &mut 0, &mut 0, &cut, |i| near.push(i));
            for i in near {
                let item = scene.items[i];
                let g = &scene.geometries[item.geometry as usize];
                if g.kind != PrimitiveKind::Triangle {
                    continue;
                }
                let GeometryData::Triangles(t) = &scene.scene.bottom_levels
                    [g.bottom_level as usize]
                    .geometries[g.geometry as usize]
                    .data
                else {
                    unreachable!("a triangle geometry")
                };
                let ids = t.vertex_indices(item.primitive as usize);
                let world = ids.map(|k| *scene.world_vertex(g, k));
                let radius = ids.map(|k| scene.static_radius(g, k));
                let instance_band = &scene.instances[g.instance as usize].band;
                let band = triangle_band(
                    instance_band,
                    &world.map(|v| v.map(|x| x.value)),
                    &radius,
                    rf.origin,
                    rf.direction,
                    rf.direction_norm,
                );
                visit(&WorkloadPair {
                    workload: w.name,
                    ray,
                    rf: &rf,
                    world,
                    radius,
                    instance_band,
                    band,
                });
            }
        }
    }
}

impl WorkloadPair<'_> {
    /// The filter's signs and values of the pair (it decides every pair of the workloads).
    pub(crate) fn filter(&self) -> (TriangleSigns, TriangleValues) {
        let ray = self.ray;
        triangle_signs::<BoundedF64>(
            &self.world,
            &v3(ray.origin),
            &v3(ray.direction),
            ray.tmin,
            ray.tmax,
            &self.band,
        )
        .expect("the filter decides the workloads' pairs")
    }

    /// The pre-test of the pair.
    pub(crate) fn pre_test(&self) -> PreTest {
        pre_test(
            self.instance_band,
            [&self.world[0], &self.world[1], &self.world[2]],
            &self.radius,
            self.rf.origin,
            self.rf.origin_norm,
            self.rf.direction,
            self.rf.direction_norm,
        )
    }
}

/// A random triangle of the pre-test's and the plain path's tests: object-space vertices at scale
/// `s`, under the identity (even `case`) or a rotation about z with a stretch along it and a
/// translation, its world vertices with their error bounds and its vertices' static radii.
pub(crate) struct RandomTriangle {
    pub(crate) transform: Transform3x4,
    pub(crate) band: InstanceBand,
    pub(crate) obj: [[f32; 3]; 3],
    pub(crate) world: [[BoundedF64; 3]; 3],
    pub(crate) radius: [f64; 3],
}

impl RandomTriangle {
    pub(crate) fn new(rng: &mut Lcg, case: usize, s: f64) -> RandomTriangle {
        let transform = if case % 2 == 0 {
            Transform3x4::IDENTITY
        } else {
            let (sn, cs) = rng.range(0.0, 6.0).sin_cos();
            let t = [0; 3].map(|_| rng.range(-5.0, 5.0) * s);
            Transform3x4([
                [cs as f32, -sn as f32, 0.0, t[0] as f32],
                [sn as f32, cs as f32, 0.0, t[1] as f32],
                [0.0, 0.0, 1.3, t[2] as f32],
            ])
        };
        let band = InstanceBand::new(&transform);
        let obj: [[f32; 3]; 3] = [0; 3].map(|_| [0; 3].map(|_| (rng.range(-1.0, 1.0) * s) as f32));
        let world = obj.map(|p| affine(&transform.0, &v3::<BoundedF64>(p)));
        let radius = obj.map(|p| {
            let o = p.map(|x| x as f64);
            vertex_static_radius(&band, None, o, o)
        });
        RandomTriangle {
            transform,
            band,
            obj,
            world,
            radius,
        }
    }
}
