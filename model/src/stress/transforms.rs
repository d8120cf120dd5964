//! Families of hard transforms: ill-conditioned instance transforms, geometry and instance
//! transforms together (two geometries with one geometry transform closing one mesh), and mirrored
//! instances under facing culls. Signed permutations scaled by powers of two keep rays exact; the
//! general transforms are aimed at in f64 and carry no aiming claim.

use super::claims::{Claim, Member};
use super::families::{geometry, shoot_many, single_geometry, Aimer, Placement, Shot, Target};
use super::mesh::LatticeMesh;
use super::StressCase;
use crate::scene::build::{similarity, SceneRng};
use crate::scene::{BottomLevel, InstanceFlags, Ray, RayFlags, Scene, SceneInstance, Transform3x4};
use crate::tracer::band::{inverse3, norm3};

/// A signed permutation scaled by `2^scale`, with a translation in granules: exact on the lattice.
#[derive(Debug, Clone, Copy)]
struct LatticeMap {
    axes: [usize; 3],
    signs: [i64; 3],
    scale: u32,
    translation: [i64; 3],
}

impl LatticeMap {
    fn random(rng: &mut SceneRng, mirror: Option<bool>, spread: i64) -> LatticeMap {
        const PERMS: [[usize; 3]; 6] = [
            [1, 2, 0],
            [2, 0, 1],
            [0, 2, 1],
            [1, 0, 2],
            [2, 1, 0],
            [0, 1, 2],
        ];
        loop {
            let axes = PERMS[rng.below(6) as usize];
            let signs = [0, 1, 2].map(|_| if rng.below(2) == 0 { 1 } else { -1 });
            let m = LatticeMap {
                axes,
                signs,
                scale: rng.below(3) as u32,
                translation: [0, 1, 2].map(|_| {
                    (rng.below((2 * spread + 1) as u64) as i64 - spread) * LatticeMesh::STEP
                }),
            };
            let identity = axes == [0, 1, 2] && signs == [1, 1, 1] && m.scale == 0;
            if !identity && mirror.is_none_or(|want| m.mirrors() == want) {
                return m;
            }
        }
    }

    /// Whether the determinant is negative.
    fn mirrors(&self) -> bool {
        let parity = match self.axes {
            [0, 1, 2] | [1, 2, 0] | [2, 0, 1] => 1,
            _ => -1,
        };
        parity * self.signs.iter().product::<i64>() < 0
    }

    /// Output row r takes input axis `axes[r]`.
    fn apply(&self, p: [i64; 3]) -> [i64; 3] {
        [0, 1, 2].map(|r| self.signs[r] * (p[self.axes[r]] << self.scale) + self.translation[r])
    }

    fn transform(&self, exponent: i32) -> Transform3x4 {
        let mut m = [[0.0f32; 4]; 3];
        for r in 0..3 {
            m[r][self.axes[r]] = (self.signs[r] as f64 * 2f64.powi(self.scale as i32)) as f32;
            m[r][3] = (self.translation[r] as f64 * 2f64.powi(exponent)) as f32;
        }
        Transform3x4(m)
    }
}

/// A ray from `distance` before the world point `p` along a random direction (f64, rounded).
fn approximate_ray(rng: &mut SceneRng, p: [f64; 3], distance: f64) -> Ray {
    let d = loop {
        let d = [0, 1, 2].map(|_| rng.range(-1.0, 1.0));
        let n = norm3(d);
        if n > 0.2 {
            break d.map(|x| x / n);
        }
    };
    let o = [0, 1, 2].map(|k| (p[k] - distance * d[k]) as f32);
    Ray::new(o, d.map(|x| x as f32), 0.0, f32::INFINITY)
}

/// A random object-space target of the mesh (a vertex, an edge point, or an interior point), f64.
fn approximate_target(rng: &mut SceneRng, mesh: &LatticeMesh, exponent: i32) -> [f64; 3] {
    let p = rng.below(mesh.triangle_count() as u64) as usize;
    let v = mesh.triangle(p).map(|i| mesh.units[i].map(|x| x as f64));
    let w = match rng.below(3) {
        0 => [1.0, 0.0, 0.0],
        1 => {
            let s = rng.unit();
            [s, 1.0 - s, 0.0]
        }
        _ => [0.25, 0.35, 0.4],
    };
    let g = 2f64.powi(exponent);
    [0, 1, 2].map(|k| (w[0] * v[0][k] + w[1] * v[1][k] + w[2] * v[2][k]) * g)
}

fn apply(m: &Transform3x4, p: [f64; 3]) -> [f64; 3] {
    m.apply_f64(p)
}

fn frobenius_condition(m: &Transform3x4) -> f64 {
    let a = m.linear_f64();
    let inv = inverse3(&a);
    let f = |x: &[[f64; 3]; 3]| x.iter().flatten().map(|v| v * v).sum::<f64>().sqrt();
    f(&a) * f(&inv)
}

/// Three instances of the closed mesh with transforms `R1 · diag(1, κ^-1/2, κ^-1) · R2 · 4`, κ
/// log-uniform in [10, 1e6], rays aimed in f64 at their vertices, edges and interiors.
pub fn ill_conditioned(seed: u64, size: usize) -> StressCase {
    let mut rng = SceneRng(seed);
    let exponent = -8;
    let mesh = LatticeMesh::jittered_cube(&mut rng, 4);
    let positions = mesh.positions(exponent, [0; 3]).expect("exact lattice");
    let mut instances = Vec::new();
    let mut claims = vec![Claim::ClosedMesh {
        bottom_level: 0,
        geometries: vec![0],
    }];
    for i in 0..3u32 {
        let (m, kappa) = loop {
            let kappa = 10f64.powf(rng.range(1.0, 6.0));
            let r1 = similarity(
                [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 1.0],
                rng.range(0.0, 6.3),
                1.0,
                false,
                [0.0; 3],
            );
            let r2 = similarity(
                [1.0, rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)],
                rng.range(0.0, 6.3),
                1.0,
                false,
                [0.0; 3],
            );
            let s = [1.0, kappa.powf(-0.5), 1.0 / kappa];
            let (a, b) = (r1.linear_f64(), r2.linear_f64());
            let mut t = Transform3x4([[0.0; 4]; 3]);
            for (row, a_row) in t.0.iter_mut().zip(&a) {
                for (c, x) in row.iter_mut().take(3).enumerate() {
                    *x = (4.0 * (0..3).map(|k| a_row[k] * s[k] * b[k][c]).sum::<f64>()) as f32;
                }
                row[3] = 40.0 * (i as f32 - 1.0);
            }
            let kf = frobenius_condition(&t);
            if (kappa / 2.0..2.0 * kappa).contains(&kf) {
                break (t, kappa);
            }
        };
        claims.push(Claim::Conditioned {
            instance: i,
            min_kappa: kappa / 2.0,
            max_kappa: kappa * 2.0,
        });
        instances.push(SceneInstance {
            transform: m,
            custom_index: i,
            ..SceneInstance::of(0)
        });
    }
    let mut case = StressCase {
        name: format!("ill-conditioned/{seed}"),
        scene: Scene {
            bottom_levels: vec![BottomLevel {
                geometries: vec![geometry(positions, Some(mesh.indices.clone()), None)],
            }],
            instances,
        },
        rays: Vec::new(),
        claims,
    };
    for k in 0..size {
        let inst = &case.scene.instances[k % 3];
        let p = apply(
            &inst.transform,
            approximate_target(&mut rng, &mesh, exponent),
        );
        case.rays.push(approximate_ray(&mut rng, p, 12.0));
    }
    case
}

/// The closed mesh split into two geometries (the ±z faces and the rest) that share one geometry
/// transform; instance 0 stacks an exact geometry transform and an exact instance transform
/// (signed permutations, powers of two; mirrored on odd seeds) and is aimed at exactly; instance 1
/// stacks general similarities (bottom level 1) and is aimed at in f64.
pub fn stacked(seed: u64, size: usize) -> StressCase {
    let mut rng = SceneRng(seed);
    let exponent = -8;
    let mesh = LatticeMesh::jittered_cube(&mut rng, 4);
    // Split: geometry 1 takes the faces across z.
    let mut members: Vec<Member> = Vec::new();
    let mut split: [Vec<u32>; 2] = [Vec::new(), Vec::new()];
    for p in 0..mesh.triangle_count() {
        let g = (mesh.faces[p] / 2 == 2) as usize;
        members.push((g as u32, (split[g].len() / 3) as u32));
        split[g].extend(mesh.triangle(p).map(|v| v as u32));
    }
    let positions = mesh.positions(exponent, [0; 3]).expect("exact lattice");
    let exact_g = LatticeMap::random(&mut rng, None, 8);
    let exact_m = LatticeMap::random(&mut rng, Some(seed % 2 == 1), 64);
    let general_g = similarity(
        [rng.range(-1.0, 1.0), 1.0, rng.range(-1.0, 1.0)],
        rng.range(0.0, 6.3),
        rng.range(0.5, 2.0),
        rng.below(2) == 0,
        [
            rng.range(-2.0, 2.0),
            rng.range(-2.0, 2.0),
            rng.range(-2.0, 2.0),
        ],
    );
    let general_m = similarity(
        [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 1.0],
        rng.range(0.0, 6.3),
        rng.range(0.5, 2.0),
        rng.below(2) == 0,
        [60.0, rng.range(-5.0, 5.0), rng.range(-5.0, 5.0)],
    );
    let level = |g: Transform3x4| BottomLevel {
        geometries: (0..2)
            .map(|k| geometry(positions.clone(), Some(split[k].clone()), Some(g)))
            .collect(),
    };
    let scene = Scene {
        bottom_levels: vec![level(exact_g.transform(exponent)), level(general_g)],
        instances: vec![
            SceneInstance {
                transform: exact_m.transform(exponent),
                ..SceneInstance::of(0)
            },
            SceneInstance {
                transform: general_m,
                custom_index: 1,
                ..SceneInstance::of(1)
            },
        ],
    };
    let mut claims = vec![
        Claim::ClosedMesh {
            bottom_level: 0,
            geometries: vec![0, 1],
        },
        Claim::ClosedMesh {
            bottom_level: 1,
            geometries: vec![0, 1],
        },
        Claim::StackedTransforms {
            instance: 0,
            geometry: 0,
        },
        Claim::StackedTransforms {
            instance: 1,
            geometry: 1,
        },
    ];
    for (i, m) in scene.instances.iter().enumerate() {
        if crate::tracer::arith::determinant_sign(&m.transform.0) == std::cmp::Ordering::Less {
            claims.push(Claim::Mirrored { instance: i as u32 });
        }
    }
    let mut case = StressCase {
        name: format!("stacked-transforms/{seed}"),
        scene,
        rays: Vec::new(),
        claims,
    };
    let world = |p: [i64; 3]| exact_m.apply(exact_g.apply(p));
    let at = Placement {
        instance: 0,
        exponent,
        object: &|p| p,
        world: &world,
        members: &members,
    };
    let shot = Shot {
        distance: 4 * LatticeMesh::CELL,
        ..Shot::DEFAULT
    };
    let targets = [Target::Edge, Target::Vertex, Target::Interior];
    shoot_many(
        &mut rng,
        &Aimer::new(&mesh),
        &at,
        &targets,
        shot,
        size.div_ceil(2),
        &mut case,
    );
    let composed = |p: [f64; 3]| apply(&general_m, apply(&general_g, p));
    while case.rays.len() < size {
        let p = composed(approximate_target(&mut rng, &mesh, exponent));
        case.rays.push(approximate_ray(&mut rng, p, 16.0));
    }
    case
}

/// Four instances of the closed mesh: an exact mirror, an exact mirror with FLIP_FACING, a general
/// mirrored similarity, and an exact non-mirrored control; a third of the rays cull back faces,
/// a third cull front faces.
pub fn mirrored(seed: u64, size: usize) -> StressCase {
    let mut rng = SceneRng(seed);
    let exponent = -8;
    let mesh = LatticeMesh::jittered_cube(&mut rng, 4);
    let positions = mesh.positions(exponent, [0; 3]).expect("exact lattice");
    let spacing = 64 * LatticeMesh::CELL;
    let mut maps = Vec::new();
    for (k, mirror) in [(0i64, true), (1, true), (3, false)] {
        let mut m = LatticeMap::random(&mut rng, Some(mirror), 0);
        m.translation = [k * spacing - spacing, 0, 0];
        maps.push(m);
    }
    let general = similarity(
        [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 1.0],
        rng.range(0.0, 6.3),
        rng.range(0.5, 2.0),
        true,
        [(spacing as f64) * 2f64.powi(exponent), 0.0, 0.0],
    );
    let exact = |i: usize| SceneInstance {
        transform: maps[i].transform(exponent),
        custom_index: i as u32,
        ..SceneInstance::of(0)
    };
    let mut flipped = exact(1);
    flipped.flags = InstanceFlags {
        flip_facing: true,
        ..InstanceFlags::default()
    };
    let scene = Scene {
        bottom_levels: vec![BottomLevel {
            geometries: vec![geometry(positions, Some(mesh.indices.clone()), None)],
        }],
        instances: vec![
            exact(0),
            flipped,
            SceneInstance {
                transform: general,
                custom_index: 2,
                ..SceneInstance::of(0)
            },
            SceneInstance {
                custom_index: 3,
                ..exact(2)
            },
        ],
    };
    let mut case = StressCase {
        name: format!("mirrored/{seed}"),
        scene,
        rays: Vec::new(),
        claims: vec![
            Claim::ClosedMesh {
                bottom_level: 0,
                geometries: vec![0],
            },
            Claim::Mirrored { instance: 0 },
            Claim::Mirrored { instance: 1 },
            Claim::Mirrored { instance: 2 },
        ],
    };
    let members = single_geometry(&mesh);
    let aimer = Aimer::new(&mesh);
    let flags = [
        RayFlags::empty(),
        RayFlags::CULL_BACK_FACING_TRIANGLES,
        RayFlags::CULL_FRONT_FACING_TRIANGLES,
    ];
    let mut attempts = 0;
    while case.rays.len() < size && attempts < 8 * size + 16 {
        attempts += 1;
        let index = case.rays.len();
        let which = rng.below(4) as usize;
        if which == 2 {
            let p = apply(&general, approximate_target(&mut rng, &mesh, exponent));
            case.rays.push(approximate_ray(&mut rng, p, 12.0));
        } else {
            // Instances 0, 1 and 3 are the exact ones: maps 0, 1 and 2.
            let map = maps[if which == 3 { 2 } else { which }];
            let world = move |p: [i64; 3]| map.apply(p);
            let at = Placement {
                instance: which as u32,
                exponent,
                object: &|p| p,
                world: &world,
                members: &members,
            };
            shoot_many(
                &mut rng,
                &aimer,
                &at,
                &[Target::Interior],
                Shot::DEFAULT,
                1,
                &mut case,
            );
        }
        if let Some(r) = case.rays.get_mut(index) {
            r.flags = flags[index % 3];
        }
    }
    case
}
