//! A built structure as the reference tracer's [`Scene`], and the rays that check it: the model's
//! primitives of a build (`build_primitives`: triangles after index and firstVertex with their geometry
//! transform, AABBs with the sphere the check's intersection shaders report, instances of the one-triangle
//! bottom level a top-level case references), inactive ones kept, and rays through every primitive
//! (interior points, varied directions) plus random rays, all deterministic.

use super::call::{BuildGeometryInfo, GeometryData as BuildData};
use super::semantics::{build_primitives, BuiltPrimitive, Shape};
use super::world::{offset, InstanceReference, Memory, RangeInfo};
use crate::call::Address;
use crate::scene::{
    Aabb, Aabbs, BottomLevel, Geometry, GeometryData, GeometryFlags, InstanceFlags, Ray, Scene,
    SceneInstance, Sphere, Transform3x4, Triangles,
};
use crate::tracer::{HitShaders, MissShader};

/// The triangle of the bottom level a top-level case's instances reference (the harness builds it
/// first): three vertices around the origin.
pub const TOP_LEVEL_TRIANGLE: [[f32; 3]; 3] =
    [[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.0, 0.5, 0.0]];

/// The shader group indices of the check (as the pipeline check lays them out; the ray query check
/// writes the same): the miss group, the triangle hit group and the procedural hit group.
pub const MISS_GROUP: u32 = 1;
pub const TRIANGLE_GROUP: u32 = 2;
pub const PROCEDURAL_GROUP: u32 = 3;

/// The ray interval of every check ray.
pub const CHECK_TMAX: f32 = 100.0;

/// Rays through each active primitive; one more through each inactive one.
const RAYS_PER_PRIMITIVE: usize = 2;
/// At most this many rays check one structure (then one ray per primitive, then fewer).
const MOST_RAYS: usize = 4096;

/// The scene the tracer sees for one build info: one bottom level (the built one, traced through one
/// identity instance) or, for a top-level build, the instances of [`TOP_LEVEL_TRIANGLE`].
pub fn build_scene(
    mem: &Memory,
    info: &BuildGeometryInfo,
    ranges: &[RangeInfo],
    prims: &[BuiltPrimitive],
    top: bool,
) -> Result<Scene, String> {
    if top {
        let blas = BottomLevel {
            geometries: vec![Geometry {
                flags: GeometryFlags::default(),
                data: GeometryData::Triangles(Triangles {
                    positions: TOP_LEVEL_TRIANGLE.to_vec(),
                    indices: None,
                    transform: None,
                }),
            }],
        };
        let instances = prims
            .iter()
            .map(|p| match &p.shape {
                Shape::Instance(rec) => {
                    let m = rec.transform;
                    Ok(SceneInstance {
                        bottom_level: (rec.reference != InstanceReference::Null).then_some(0),
                        transform: Transform3x4(
                            [0, 1, 2].map(|r| [m[4 * r], m[4 * r + 1], m[4 * r + 2], m[4 * r + 3]]),
                        ),
                        custom_index: rec.custom_index,
                        mask: rec.mask,
                        sbt_record_offset: rec.sbt_offset,
                        flags: InstanceFlags {
                            triangle_facing_cull_disable: rec.flags & 1 != 0,
                            flip_facing: rec.flags & 2 != 0,
                            force_opaque: rec.flags & 4 != 0,
                            force_no_opaque: rec.flags & 8 != 0,
                        },
                    })
                }
                _ => Err(format!(
                    "geometry {} primitive {} of a top-level build is not an instance",
                    p.geometry, p.primitive
                )),
            })
            .collect::<Result<Vec<_>, String>>()?;
        return Ok(Scene {
            bottom_levels: vec![blas],
            instances,
        });
    }
    // Object-space vertices: the same build without geometry transforms; the transforms go to the
    // scene, so the tracer bounds their rounding as the device's build incurs it.
    let mut untransformed = info.clone();
    for g in &mut untransformed.geometries {
        if let BuildData::Triangles { transform_data, .. } = &mut g.data {
            *transform_data = Address::NULL;
        }
    }
    let raw = build_primitives(mem, &untransformed, ranges).map_err(|e| e.to_string())?;
    let mut geometries = Vec::with_capacity(info.geometries.len());
    for (g, (geom, range)) in info.geometries.iter().zip(ranges).enumerate() {
        let flags = GeometryFlags {
            opaque: geom.flags.0 & 1 != 0,
            no_duplicate_any_hit: geom.flags.0 & 2 != 0,
        };
        let of_g = |p: &&BuiltPrimitive| p.geometry == g as u32;
        let data = match &geom.data {
            BuildData::Triangles { transform_data, .. } => {
                let transform = if transform_data.is_null() {
                    None
                } else {
                    let a = offset(transform_data, range.transform_offset as u64);
                    let mut m = [[0.0f32; 4]; 3];
                    for (k, v) in m.iter_mut().flatten().enumerate() {
                        *v = mem
                            .f32_at(&offset(&a, 4 * k as u64))
                            .ok_or_else(|| format!("pGeometries[{g}]: transform unreadable"))?;
                    }
                    Some(Transform3x4(m))
                };
                let mut positions = Vec::new();
                for p in raw.iter().filter(of_g) {
                    let Shape::Triangle(v) = &p.shape else {
                        return Err(format!("pGeometries[{g}]: not triangles"));
                    };
                    // An inactive triangle stays (it keeps its PrimitiveId); what else it holds
                    // has no meaning, so non-finite Y and Z become 0.
                    let clean = |x: f32| if p.active || x.is_finite() { x } else { 0.0 };
                    positions.extend(v.iter().map(|q| [q[0], clean(q[1]), clean(q[2])]));
                }
                GeometryData::Triangles(Triangles {
                    positions,
                    indices: None,
                    transform,
                })
            }
            BuildData::Aabbs { .. } => {
                let mut boxes = Vec::new();
                let mut spheres = Vec::new();
                for p in prims.iter().filter(of_g) {
                    let Shape::Aabb { min, max } = &p.shape else {
                        return Err(format!("pGeometries[{g}]: not AABBs"));
                    };
                    let (min, max) = if p.active {
                        (*min, *max)
                    } else {
                        let clean = |x: f32| if x.is_finite() { x } else { 0.0 };
                        ([f32::NAN, clean(min[1]), clean(min[2])], max.map(clean))
                    };
                    boxes.push(Aabb { min, max });
                    spheres.push(if p.active {
                        inscribed(&min, &max)
                    } else {
                        Sphere {
                            center: [0.0; 3],
                            radius: 1.0,
                        }
                    });
                }
                GeometryData::Aabbs(Aabbs { boxes, spheres })
            }
            _ => {
                return Err(format!(
                    "pGeometries[{g}]: the check traces triangles and AABBs"
                ))
            }
        };
        geometries.push(Geometry { flags, data });
    }
    Ok(Scene {
        bottom_levels: vec![BottomLevel { geometries }],
        instances: vec![SceneInstance::of(0)],
    })
}

/// The sphere a box's intersection shader reports: centred in the box, radius 7/16 of its smallest side
/// (inside the box whatever the rounding of the centre).
pub fn inscribed(min: &[f32; 3], max: &[f32; 3]) -> Sphere {
    let center = [0, 1, 2].map(|k| min[k] * 0.5 + max[k] * 0.5);
    let side = (0..3)
        .map(|k| max[k] - min[k])
        .fold(f32::INFINITY, f32::min);
    Sphere {
        center,
        radius: side * 0.4375,
    }
}

/// The hit groups of the check: every triangle geometry the triangle group, every AABB geometry the
/// procedural group (closest-hit and the sphere intersection shader), no any-hit shader.
pub fn check_hit_shaders(scene: &Scene, geometry: u32) -> HitShaders {
    let procedural = scene
        .bottom_levels
        .first()
        .and_then(|b| b.geometries.get(geometry as usize))
        .is_some_and(|g| matches!(g.data, GeometryData::Aabbs(_)));
    if procedural {
        HitShaders::procedural(PROCEDURAL_GROUP, None)
    } else {
        HitShaders::closest(TRIANGLE_GROUP)
    }
}

/// The check's miss record.
pub const CHECK_MISS: MissShader = MissShader {
    zero_group: false,
    group: MISS_GROUP,
};

/// A small deterministic generator (splitmix64).
struct Draw(u64);

impl Draw {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// A direction uniform on the sphere.
    fn direction(&mut self) -> [f64; 3] {
        let z = 2.0 * self.unit() - 1.0;
        let a = std::f64::consts::TAU * self.unit();
        let r = (1.0 - z * z).max(0.0).sqrt();
        [r * a.cos(), r * a.sin(), z]
    }
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// A ray aimed at `point` from distance 2 along `dir`, or None when it is not finite.
fn aimed(point: [f64; 3], dir: [f64; 3]) -> Option<Ray> {
    let o = [0, 1, 2].map(|k| (point[k] - 2.0 * dir[k]) as f32);
    let d = dir.map(|x| x as f32);
    (o.iter().chain(&d).all(|x| x.is_finite()) && d.iter().any(|x| *x != 0.0))
        .then(|| Ray::new(o, d, 0.0, CHECK_TMAX))
}

/// A direction through a triangle of normal `n` (never within about 17° of its plane).
fn across(draw: &mut Draw, n: [f64; 3]) -> [f64; 3] {
    let d = draw.direction();
    let l = norm(n);
    if !l.is_finite() || l <= 0.0 {
        return d;
    }
    let n = n.map(|x| x / l);
    let c = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
    if c.abs() >= 0.3 {
        return d;
    }
    let s = if c < 0.0 { -1.0 } else { 1.0 };
    let m = [0, 1, 2].map(|k| d[k] + s * 0.6 * n[k]);
    let lm = norm(m);
    m.map(|x| x / lm)
}

/// A point inside the triangle `v` (barycentric weights at least 0.1 each).
fn interior(draw: &mut Draw, v: &[[f64; 3]; 3]) -> [f64; 3] {
    let (mut b, mut c) = (draw.unit(), draw.unit());
    if b + c > 1.0 {
        (b, c) = (1.0 - b, 1.0 - c);
    }
    let (b, c) = (0.1 + 0.7 * b, 0.1 + 0.7 * c);
    let a = 1.0 - b - c;
    [0, 1, 2].map(|k| a * v[0][k] + b * v[1][k] + c * v[2][k])
}

fn normal(v: &[[f64; 3]; 3]) -> [f64; 3] {
    let e1 = [0, 1, 2].map(|k| v[1][k] - v[0][k]);
    let e2 = [0, 1, 2].map(|k| v[2][k] - v[0][k]);
    [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ]
}

/// The rays that check a built structure: through each active primitive at interior points from
/// varied directions, through where each inactive one would be (it must not be hit), then random
/// rays through the scene's bounds. Deterministic for a given build.
pub fn check_rays(prims: &[BuiltPrimitive]) -> Vec<Ray> {
    let mut draw = Draw(0x5EED_0000 ^ prims.len() as u64);
    let per = if prims.len() * (RAYS_PER_PRIMITIVE + 1) <= MOST_RAYS {
        RAYS_PER_PRIMITIVE
    } else {
        1
    };
    let mut rays = Vec::new();
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let mut grow = |p: [f64; 3]| {
        if p.iter().all(|x| x.is_finite()) {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    };
    for p in prims {
        if rays.len() >= MOST_RAYS {
            break;
        }
        let f = |q: [f32; 3]| q.map(|x| x as f64);
        match &p.shape {
            Shape::Triangle(v) => {
                let v = v.map(f);
                if p.active {
                    v.iter().for_each(|q| grow(*q));
                    for _ in 0..per {
                        let d = across(&mut draw, normal(&v));
                        rays.extend(aimed(interior(&mut draw, &v), d));
                    }
                } else {
                    // Where it would be: between its other two vertices, from above.
                    let m = [0, 1, 2].map(|k| 0.5 * (v[1][k] + v[2][k]));
                    rays.extend(aimed(m, [0.0, 0.0, 1.0]));
                }
            }
            Shape::Aabb { min, max } => {
                if p.active {
                    grow(f(*min));
                    grow(f(*max));
                    let s = inscribed(min, max);
                    let c = f(s.center);
                    for _ in 0..per {
                        let d = draw.direction();
                        let j = draw.direction().map(|x| x * 0.5 * s.radius as f64);
                        rays.extend(aimed([0, 1, 2].map(|k| c[k] + j[k]), d));
                    }
                } else {
                    let m = [max[0] as f64 - 0.5, 0.5 * (min[1] + max[1]) as f64, 0.0];
                    rays.extend(aimed(m, [0.0, 0.0, 1.0]));
                }
            }
            Shape::Instance(rec) => {
                let m = rec.transform;
                let world = |q: [f32; 3]| {
                    [0, 1, 2].map(|r| {
                        m[4 * r] as f64 * q[0] as f64
                            + m[4 * r + 1] as f64 * q[1] as f64
                            + m[4 * r + 2] as f64 * q[2] as f64
                            + m[4 * r + 3] as f64
                    })
                };
                let v = TOP_LEVEL_TRIANGLE.map(world);
                if p.active {
                    v.iter().for_each(|q| grow(*q));
                }
                for _ in 0..if p.active { per } else { 1 } {
                    let d = across(&mut draw, normal(&v));
                    rays.extend(aimed(interior(&mut draw, &v), d));
                }
            }
        }
    }
    if lo[0].is_nan() || hi[0].is_nan() || lo[0] > hi[0] {
        (lo, hi) = ([-1.0; 3], [1.0; 3]);
    }
    let random = (8 + prims.len() / 2).min(MOST_RAYS.saturating_sub(rays.len()));
    for _ in 0..random {
        let p = [0, 1, 2].map(|k| lo[k] - 1.0 + (hi[k] - lo[k] + 2.0) * draw.unit());
        let d = draw.direction();
        rays.extend(aimed(p, d));
    }
    rays
}
