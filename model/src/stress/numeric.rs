//! Families of hard single triangles and hard rays: slivers and tiny triangles, grazing rays, very
//! long and very short rays, and ray intervals that end a few ULPs from the hit.

use super::claims::{Claim, TLimit};
use super::families::{geometry, shoot_many, single_geometry, Aimer, Placement, Shot, Target};
use super::mesh::LatticeMesh;
use super::StressCase;
use crate::scene::build::SceneRng;
use crate::scene::{BottomLevel, Ray, Scene, SceneInstance};

/// An axis permutation with signs: local `(u, v, w)` → world `xyz`, exact in f32.
#[derive(Debug, Clone, Copy)]
struct Frame {
    axes: [usize; 3],
    signs: [f64; 3],
}

impl Frame {
    fn random(rng: &mut SceneRng) -> Frame {
        const PERMS: [[usize; 3]; 6] = [
            [0, 1, 2],
            [0, 2, 1],
            [1, 0, 2],
            [1, 2, 0],
            [2, 0, 1],
            [2, 1, 0],
        ];
        Frame {
            axes: PERMS[rng.below(6) as usize],
            signs: [0, 1, 2].map(|_| if rng.below(2) == 0 { 1.0 } else { -1.0 }),
        }
    }

    /// The world point of local coordinates; `None` unless every coordinate is an exact f32.
    fn world(&self, local: [f64; 3]) -> Option<[f32; 3]> {
        let mut out = [0.0f32; 3];
        for k in 0..3 {
            let x = self.signs[k] * local[k];
            let f = x as f32;
            if f as f64 != x || !(f == 0.0 || f.is_normal()) {
                return None;
            }
            out[self.axes[k]] = f;
        }
        Some(out)
    }
}

fn one_geometry_case(name: String, positions: Vec<[f32; 3]>) -> StressCase {
    StressCase {
        name,
        scene: Scene {
            bottom_levels: vec![BottomLevel {
                geometries: vec![geometry(positions, None, None)],
            }],
            instances: vec![SceneInstance::of(0)],
        },
        rays: Vec::new(),
        claims: Vec::new(),
    }
}

/// Pushes a triangle and its ray when the claims hold; otherwise leaves the case as it was.
fn try_push(
    case: &mut StressCase,
    g: usize,
    tri: [[f32; 3]; 3],
    ray: Ray,
    claims: Vec<Claim>,
) -> bool {
    let crate::scene::GeometryData::Triangles(t) =
        &mut case.scene.bottom_levels[0].geometries[g].data
    else {
        unreachable!("triangle geometry")
    };
    t.positions.extend(tri);
    case.rays.push(ray);
    if claims.iter().all(|c| c.check(case).is_ok()) {
        case.claims.extend(claims);
        return true;
    }
    let crate::scene::GeometryData::Triangles(t) =
        &mut case.scene.bottom_levels[0].geometries[g].data
    else {
        unreachable!("triangle geometry")
    };
    t.positions.truncate(t.positions.len() - 3);
    case.rays.pop();
    false
}

fn primitive_count(case: &StressCase, g: usize) -> u32 {
    match &case.scene.bottom_levels[0].geometries[g].data {
        crate::scene::GeometryData::Triangles(t) => t.primitive_count() as u32,
        crate::scene::GeometryData::Aabbs(_) => 0,
    }
}

/// Geometry 0: needles `(0,0) (L,0) (x,h)` with `h/L = 2^-k`, k in [8, 22], in axis-aligned planes,
/// hit inside from rays without a component along the needle's thin axis. Geometry 1: triangles
/// `n · 2^j` ULPs across (j in [0, 14]) at points 1..8 from the origin, hit from near the origin.
pub fn slivers_and_tiny(seed: u64, size: usize) -> StressCase {
    let mut rng = SceneRng(seed);
    let mut case = one_geometry_case(format!("slivers-and-tiny/{seed}"), Vec::new());
    case.scene.bottom_levels[0]
        .geometries
        .push(geometry(Vec::new(), None, None));
    let mut attempts = 0;
    while case.rays.len() < size && attempts < 16 * size + 16 {
        attempts += 1;
        let ray_index = case.rays.len() as u32;
        if case.rays.len() % 2 == 0 {
            // A sliver.
            let k = 8 + rng.below(15) as i32;
            let l = 2f64.powi(rng.below(5) as i32 - 2);
            let h = l * 2f64.powi(-k);
            let q = rng.below(25) as f64 - 4.0;
            let x = l * q / 16.0;
            let base_u = (rng.below(33) as f64 - 16.0) / 4.0;
            let plane = (rng.below(65) as f64 - 32.0) / 16.0;
            let frame = Frame::random(&mut rng);
            let local = [[0.0, 0.0], [l, 0.0], [x, h]];
            let Some(tri) = local
                .iter()
                .map(|p| frame.world([base_u + p[0], p[1], plane]))
                .collect::<Option<Vec<_>>>()
            else {
                continue;
            };
            // Inside at v = h/4: u strictly between q/64 and (48 + q)/64 of L.
            let j = q + 1.0 + rng.below(47) as f64;
            let m = [base_u + l * j / 64.0, h / 4.0, plane];
            let du = rng.below(15) as f64 - 7.0;
            let dw = (1 + rng.below(7)) as f64 * if rng.below(2) == 0 { 1.0 } else { -1.0 };
            let dist = l / 4.0;
            let (Some(o), Some(d)) = (
                frame.world([m[0] - dist * du, m[1], m[2] - dist * dw]),
                frame.world([du, 0.0, dw]),
            ) else {
                continue;
            };
            let member = (0, primitive_count(&case, 0));
            let claims = vec![
                Claim::Sliver {
                    instance: 0,
                    member,
                    max_aspect: 2f64.powi(-k),
                },
                Claim::ThroughInterior {
                    ray: ray_index,
                    instance: 0,
                    member,
                },
            ];
            let tri = [tri[0], tri[1], tri[2]];
            try_push(
                &mut case,
                0,
                tri,
                Ray::new(o, d, 0.0, f32::INFINITY),
                claims,
            );
        } else {
            // A tiny triangle at B, vertex offsets multiples of 2^j ULPs of B's largest component.
            let e = rng.below(3) as i32;
            let b: [f64; 3] = [0, 1, 2].map(|_| {
                let m = (10 + rng.below(5)) as f64 / 8.0 * 2f64.powi(e);
                if rng.below(2) == 0 {
                    m
                } else {
                    -m
                }
            });
            let top = b.iter().map(|x| x.abs()).fold(0.0, f64::max);
            let ulp = 2f64.powi(top.log2().floor() as i32 - 23);
            let j = rng.below(15) as i32;
            let step = ulp * 2f64.powi(j);
            let offsets: [[i64; 3]; 2] =
                [0, 1].map(|_| [0, 1, 2].map(|_| rng.below(17) as i64 - 8));
            let (p, r) = (offsets[0], offsets[1]);
            let cross = [
                p[1] * r[2] - p[2] * r[1],
                p[2] * r[0] - p[0] * r[2],
                p[0] * r[1] - p[1] * r[0],
            ];
            if cross == [0, 0, 0] {
                continue;
            }
            let vertex = |o: [i64; 3]| [0, 1, 2].map(|k| (b[k] + o[k] as f64 * step) as f32);
            let tri = [vertex([0; 3]), vertex(p), vertex(r)];
            // Exactness of every vertex.
            let exact = (0..3).all(|k| {
                [[0i64; 3], p, r]
                    .iter()
                    .all(|o| (b[k] + o[k] as f64 * step) as f32 as f64 == b[k] + o[k] as f64 * step)
            });
            if !exact {
                continue;
            }
            let w1 = 3 + rng.below(8) as i64;
            let w2 = 3 + rng.below((11 - w1) as u64) as i64;
            // o = (w1·p + w2·r)/16 · step; d = B; o + 1·d is the interior point.
            let o = [0, 1, 2].map(|k| ((w1 * p[k] + w2 * r[k]) as f64 / 16.0 * step) as f32);
            let d = b.map(|x| x as f32);
            let member = (1, primitive_count(&case, 1));
            let extent = 28.0 * step;
            let claims = vec![
                Claim::Tiny {
                    instance: 0,
                    member,
                    max_extent: extent,
                },
                Claim::ThroughInterior {
                    ray: ray_index,
                    instance: 0,
                    member,
                },
            ];
            try_push(
                &mut case,
                1,
                tri,
                Ray::new(o, d, 0.0, f32::INFINITY),
                claims,
            );
        }
    }
    case
}

/// Triangles in axis-aligned planes and in the plane x + y = c, hit inside by rays at a sine of
/// about 2^-3..2^-18 to the plane; one ray in eight lies exactly in an axis-aligned plane.
pub fn grazing(seed: u64, size: usize) -> StressCase {
    let mut rng = SceneRng(seed);
    let mut case = one_geometry_case(format!("grazing/{seed}"), Vec::new());
    let mut attempts = 0;
    while case.rays.len() < size && attempts < 16 * size + 16 {
        attempts += 1;
        let ray_index = case.rays.len() as u32;
        let grid = |rng: &mut SceneRng| (rng.below(65) as f64 - 32.0) / 16.0;
        let k = 3 + rng.below(16) as i32;
        let eps = 2f64.powi(-k) * if rng.below(2) == 0 { 1.0 } else { -1.0 };
        let tilted = rng.below(2) == 0;
        let in_plane = !tilted && rng.below(8) == 0;
        let eps = if in_plane { 0.0 } else { eps };
        let (a, b2) = (rng.below(15) as f64 - 7.0, rng.below(15) as f64 - 7.0);
        if a == 0.0 && b2 == 0.0 {
            continue;
        }
        let dist = 4.0;
        type Aimed = ([[f32; 3]; 3], Option<[f32; 3]>, Option<[f32; 3]>);
        let (tri, o, d): Aimed = if tilted {
            // Plane x + y = c: points (x, c − x, z); in-plane direction (a, −a, b2); normal (1, 1, 0).
            let c = grid(&mut rng);
            let pts: Vec<[f64; 3]> = (0..3)
                .map(|_| {
                    let x = grid(&mut rng);
                    [x, c - x, grid(&mut rng)]
                })
                .collect();
            let tri = [0, 1, 2].map(|i| pts[i].map(|x| x as f32));
            let w1 = (3 + rng.below(8)) as f64;
            let w2 = (3 + rng.below(11 - w1 as u64)) as f64;
            let w0 = 16.0 - w1 - w2;
            let m = [0, 1, 2].map(|k| (w0 * pts[0][k] + w1 * pts[1][k] + w2 * pts[2][k]) / 16.0);
            let d = [a + eps, -a + eps, b2];
            let o = [0, 1, 2].map(|k| m[k] - dist * d[k]);
            let exact = |v: [f64; 3]| {
                v.iter()
                    .all(|x| (*x as f32) as f64 == *x)
                    .then(|| v.map(|x| x as f32))
            };
            (tri, exact(o), exact(d))
        } else {
            let frame = Frame::random(&mut rng);
            let plane = grid(&mut rng);
            let pts: Vec<[f64; 3]> = (0..3)
                .map(|_| [grid(&mut rng), grid(&mut rng), plane])
                .collect();
            let Some(tri) = pts
                .iter()
                .map(|p| frame.world(*p))
                .collect::<Option<Vec<_>>>()
            else {
                continue;
            };
            let w1 = (3 + rng.below(8)) as f64;
            let w2 = (3 + rng.below(11 - w1 as u64)) as f64;
            let w0 = 16.0 - w1 - w2;
            let m = [0, 1, 2].map(|k| (w0 * pts[0][k] + w1 * pts[1][k] + w2 * pts[2][k]) / 16.0);
            let d = [a, b2, eps];
            let o = [0, 1, 2].map(|k| m[k] - dist * d[k]);
            ([tri[0], tri[1], tri[2]], frame.world(o), frame.world(d))
        };
        let (Some(o), Some(d)) = (o, d) else {
            continue;
        };
        // The sine's bound, from f64 (the claim proves it exactly).
        let n = cross(sub(tri[1], tri[0]), sub(tri[2], tri[0]));
        let df = d.map(|x| x as f64);
        let sine = dot(df, n).abs() / (dot(df, df).sqrt() * dot(n, n).sqrt());
        if !sine.is_finite() {
            continue;
        }
        let member = (0, primitive_count(&case, 0));
        let mut claims = vec![Claim::Grazing {
            ray: ray_index,
            instance: 0,
            member,
            max_sine: sine * (1.0 + 1e-9),
        }];
        if !in_plane {
            claims.push(Claim::ThroughInterior {
                ray: ray_index,
                instance: 0,
                member,
            });
        }
        try_push(
            &mut case,
            0,
            tri,
            Ray::new(o, d, 0.0, f32::INFINITY),
            claims,
        );
    }
    case
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f64; 3] {
    [0, 1, 2].map(|k| a[k] as f64 - b[k] as f64)
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn lattice_case(name: String, rng: &mut SceneRng, exponent: i32) -> (StressCase, LatticeMesh) {
    let mesh = LatticeMesh::jittered_cube(rng, 4);
    let positions = mesh.positions(exponent, [0; 3]).expect("exact lattice");
    let case = StressCase {
        name,
        scene: Scene {
            bottom_levels: vec![BottomLevel {
                geometries: vec![geometry(positions, Some(mesh.indices.clone()), None)],
            }],
            instances: vec![SceneInstance::of(0)],
        },
        rays: Vec::new(),
        claims: vec![Claim::ClosedMesh {
            bottom_level: 0,
            geometries: vec![0],
        }],
    };
    (case, mesh)
}

/// The closed mesh (about 8 across) hit through edges, vertices and interiors by rays whose
/// directions are scaled by 2^-40..2^40 and whose origins stand 2^-18..2^10 (times the integer
/// direction's length, up to 12) before the target: very short and very long rays.
pub fn ray_length(seed: u64, size: usize) -> StressCase {
    let mut rng = SceneRng(seed);
    // Granules of 2^-18 so that origins 2^-10 direction lengths from a target stay integral.
    let fine = 10;
    let exponent = -8 - fine;
    let (mut case, mesh) = lattice_case(format!("ray-length/{seed}"), &mut rng, -8);
    let scaled = LatticeMesh {
        units: mesh.units.iter().map(|p| p.map(|x| x << fine)).collect(),
        ..mesh.clone()
    };
    let members = single_geometry(&scaled);
    let identity = |p: [i64; 3]| p;
    let at = Placement {
        instance: 0,
        exponent,
        object: &identity,
        world: &identity,
        members: &members,
    };
    let aimer = Aimer::new(&scaled);
    let targets = [Target::Edge, Target::Vertex, Target::Interior];
    while case.rays.len() < size {
        let before = case.rays.len();
        let direction_exponent = rng.below(81) as i32 - 40;
        let distance = 1i64 << rng.below(29);
        let shot = Shot {
            distance,
            direction_max: 7,
            direction_exponent,
            tmax: f32::INFINITY,
        };
        shoot_many(&mut rng, &aimer, &at, &targets, shot, 1, &mut case);
        if case.rays.len() > before {
            let r = case.rays[before];
            let base = r
                .direction
                .map(|x| (x as f64 * 2f64.powi(-direction_exponent)) as f32);
            case.claims.push(Claim::ScaledDirection {
                ray: before as u32,
                base,
                exponent: direction_exponent,
            });
        } else if case.rays.len() == before && rng.below(64) == 0 {
            break;
        }
    }
    case
}

/// The closed mesh hit inside, with tmin or tmax set 1..4 ULPs before or after the exact t (for a
/// third of the rays the exact t is not an f32 at all). The model must class these VARY.
pub fn t_window(seed: u64, size: usize) -> StressCase {
    let mut rng = SceneRng(seed);
    let exponent = -8;
    let (mut case, mesh) = lattice_case(format!("t-window/{seed}"), &mut rng, exponent);
    let members = single_geometry(&mesh);
    let identity = |p: [i64; 3]| p;
    let at = Placement {
        instance: 0,
        exponent,
        object: &identity,
        world: &identity,
        members: &members,
    };
    let aimer = Aimer::new(&mesh);
    let mut attempts = 0;
    while case.rays.len() < size && attempts < 8 * size + 16 {
        attempts += 1;
        let index = case.rays.len();
        let claims_before = case.claims.len();
        shoot_many(
            &mut rng,
            &aimer,
            &at,
            &[Target::Interior],
            Shot::DEFAULT,
            1,
            &mut case,
        );
        if case.rays.len() == index {
            continue;
        }
        let Some(Claim::ThroughInterior { member, .. }) = case.claims.pop() else {
            unreachable!("an interior shot claims its triangle")
        };
        let mut ray = case.rays[index];
        // t = distance · 2^exponent exactly; a third of the rays divide the direction's scale
        // by three (direction × 3), so t is a third of that: not an f32.
        let mut t = Shot::DEFAULT.distance as f64 * 2f64.powi(exponent);
        if rng.below(3) == 0 {
            ray.direction = ray.direction.map(|x| x * 3.0);
            t /= 3.0;
        }
        let k = 1 + rng.below(4) as i32;
        let up = rng.below(2) == 0;
        let mut lim = t as f32;
        for _ in 0..k {
            lim = if up {
                f32::from_bits(lim.to_bits() + 1)
            } else {
                f32::from_bits(lim.to_bits() - 1)
            };
        }
        let limit = if rng.below(2) == 0 {
            ray.tmin = lim;
            TLimit::Tmin
        } else {
            ray.tmax = lim;
            TLimit::Tmax
        };
        case.rays[index] = ray;
        let claim = Claim::TWindow {
            ray: index as u32,
            instance: 0,
            member,
            limit,
            max_ulps: k as u32 + 1,
        };
        if claim.check(&case).is_ok() {
            case.claims.push(claim);
        } else {
            case.rays.truncate(index);
            case.claims.truncate(claims_before);
        }
    }
    case
}
