//! The family list, and the families built on the exact closed mesh: watertightness through shared
//! edges and vertices, geometry far from the origin, extreme scales, and large meshes.

use super::aim::{self, exact_ray};
use super::claims::{Claim, Member};
use super::mesh::{exact_point, LatticeMesh, SharedEdge};
use super::{numeric, transforms, Family, StressCase};
use crate::scene::build::{pinhole_rays, SceneRng};
use crate::scene::{
    BottomLevel, Geometry, GeometryData, GeometryFlags, Indices, Ray, Scene, SceneInstance,
    Transform3x4, Triangles,
};

/// Every family, with the sizes `cargo test` and `rtconf stress` use.
pub fn families() -> Vec<Family> {
    let f = |name, about, generate, test_size, full_size| Family {
        name,
        about,
        generate,
        test_size,
        full_size,
    };
    vec![
        f(
            "watertight-edges",
            "closed mesh, rays exactly through points of shared edges",
            watertight_edges as fn(u64, usize) -> StressCase,
            48,
            4096,
        ),
        f(
            "watertight-vertices",
            "closed mesh, rays exactly through shared vertices (closed fans)",
            watertight_vertices,
            48,
            4096,
        ),
        f(
            "far-from-origin",
            "closed mesh translated 1e3..1e7, baked and by instance, exact in f32",
            far_from_origin,
            48,
            4096,
        ),
        f(
            "extreme-scale",
            "closed mesh scaled by 2^-76..2^56 (coordinates 1e-20..1e20)",
            extreme_scale,
            48,
            4096,
        ),
        f(
            "slivers-and-tiny",
            "needles of aspect 2^-8..2^-22 and triangles a few ULPs across",
            numeric::slivers_and_tiny,
            48,
            4096,
        ),
        f(
            "grazing",
            "rays at 2^-3..2^-18 to the triangle's plane, and in it",
            numeric::grazing,
            48,
            4096,
        ),
        f(
            "ray-length",
            "directions scaled 2^-40..2^40, origins 2^-18..2^13 from the hit",
            numeric::ray_length,
            48,
            4096,
        ),
        f(
            "t-window",
            "tmin or tmax 1..4 ULPs from the exact hit (VARY, never REQ)",
            numeric::t_window,
            48,
            4096,
        ),
        f(
            "ill-conditioned",
            "instance transforms of condition number 1e1..1e6",
            transforms::ill_conditioned,
            48,
            4096,
        ),
        f(
            "stacked-transforms",
            "geometry and instance transforms together, two geometries closing one mesh",
            transforms::stacked,
            48,
            4096,
        ),
        f(
            "mirrored",
            "instances with negative determinant, with flip-facing and facing culls",
            transforms::mirrored,
            48,
            4096,
        ),
        f(
            "large-mesh",
            "closed meshes of 2000·size triangles (1e6 at full size), edge and camera rays",
            large_mesh,
            16,
            512,
        ),
    ]
}

/// A non-opaque triangle geometry (so the any-hit shader sees every candidate).
pub(super) fn geometry(
    positions: Vec<[f32; 3]>,
    indices: Option<Vec<u32>>,
    transform: Option<Transform3x4>,
) -> Geometry {
    Geometry {
        flags: GeometryFlags {
            opaque: false,
            no_duplicate_any_hit: false,
        },
        data: GeometryData::Triangles(Triangles {
            positions,
            indices: indices.map(|ix| {
                if ix.iter().all(|&i| i <= u16::MAX as u32) {
                    Indices::U16(ix.iter().map(|&i| i as u16).collect())
                } else {
                    Indices::U32(ix)
                }
            }),
            transform,
        }),
    }
}

/// Where a lattice mesh stands: object units map to world units by `world`, f32 values are units
/// times `2^exponent`, and triangle `p` of the mesh is member `members[p]` of `instance`.
pub(super) struct Placement<'a> {
    pub instance: u32,
    pub exponent: i32,
    /// Object units → object-space units as stored in the bottom level (a baked translation).
    pub object: &'a dyn Fn([i64; 3]) -> [i64; 3],
    /// Object units → world units.
    pub world: &'a dyn Fn([i64; 3]) -> [i64; 3],
    pub members: &'a [Member],
}

/// What a ray is aimed at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Target {
    Edge,
    Vertex,
    Interior,
}

/// Exact aiming at one lattice mesh.
pub(super) struct Aimer<'a> {
    pub mesh: &'a LatticeMesh,
    pub edges: Vec<SharedEdge>,
    pub fans: Vec<Vec<usize>>,
    /// The triangles around each vertex of the scene being aimed at, for the vertex claims each
    /// shot proves (the case's final proof builds its own).
    pub index: std::cell::RefCell<super::FanIndex>,
}

/// How a ray is aimed: origin `distance` direction lengths before the target, direction scaled by
/// `2^direction_exponent`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Shot {
    pub distance: i64,
    pub direction_max: i64,
    pub direction_exponent: i32,
    pub tmax: f32,
}

impl Shot {
    pub const DEFAULT: Shot = Shot {
        distance: 2 * LatticeMesh::CELL,
        direction_max: 7,
        direction_exponent: 0,
        tmax: f32::INFINITY,
    };
}

impl<'a> Aimer<'a> {
    pub fn new(mesh: &'a LatticeMesh) -> Aimer<'a> {
        Aimer {
            mesh,
            edges: mesh.shared_edges(),
            fans: mesh.fans(),
            index: Default::default(),
        }
    }

    /// One ray at a random target of the kind, with the claim that it hits it exactly; `None`
    /// when no exact ray was found in a few draws (the claim is proven before it is returned).
    pub fn shoot(
        &self,
        rng: &mut SceneRng,
        target: Target,
        at: &Placement<'_>,
        shot: Shot,
        ray_index: u32,
        case: &mut StressCase,
    ) -> Option<Ray> {
        for _ in 0..16 {
            let (point, claim) = self.target(rng, target, at, ray_index)?;
            let d = aim::direction(rng, shot.direction_max);
            let o = aim::origin(point, d, shot.distance);
            let Some(ray) = exact_ray(o, at.exponent, d, shot.direction_exponent, shot.tmax) else {
                continue;
            };
            let index = ray_index as usize;
            if case.rays.len() <= index {
                case.rays.resize(index + 1, ray);
            }
            case.rays[index] = ray;
            if claim
                .check_indexed(case, &mut self.index.borrow_mut())
                .is_ok()
            {
                case.claims.push(claim);
                return Some(ray);
            }
        }
        None
    }

    fn target(
        &self,
        rng: &mut SceneRng,
        target: Target,
        at: &Placement<'_>,
        ray: u32,
    ) -> Option<([i64; 3], Claim)> {
        let world = |v: usize| (at.world)(self.mesh.units[v]);
        Some(match target {
            Target::Edge => {
                let e = self.edges[rng.below(self.edges.len() as u64) as usize];
                let (a, b) = (world(e.from), world(e.to));
                let j = 2 * rng.below(8) as i64 + 1;
                let p = [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * j / LatticeMesh::STEP);
                (
                    p,
                    Claim::ThroughSharedEdge {
                        ray,
                        instance: at.instance,
                        first: at.members[e.first],
                        second: at.members[e.second],
                    },
                )
            }
            Target::Vertex => {
                let v = rng.below(self.mesh.units.len() as u64) as usize;
                let object = exact_point((at.object)(self.mesh.units[v]), at.exponent)?;
                (
                    world(v),
                    Claim::ThroughSharedVertex {
                        ray,
                        instance: at.instance,
                        vertex: object,
                        fan: self.fans[v].iter().map(|&p| at.members[p]).collect(),
                    },
                )
            }
            Target::Interior => {
                let p = rng.below(self.mesh.triangle_count() as u64) as usize;
                let corners = self.mesh.triangle(p).map(world);
                (
                    aim::interior_point(rng, corners),
                    Claim::ThroughInterior {
                        ray,
                        instance: at.instance,
                        member: at.members[p],
                    },
                )
            }
        })
    }
}

fn identity(p: [i64; 3]) -> [i64; 3] {
    p
}

/// Members of a one-geometry mesh: triangle p is primitive p of geometry 0.
pub(super) fn single_geometry(mesh: &LatticeMesh) -> Vec<Member> {
    (0..mesh.triangle_count() as u32).map(|p| (0, p)).collect()
}

/// The jittered cube as the only bottom level and instance, f32 values `units · 2^exponent`.
fn cube_case(name: String, mesh: &LatticeMesh, exponent: i32) -> StressCase {
    let positions = mesh.positions(exponent, [0; 3]).expect("exact lattice");
    StressCase {
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
    }
}

/// Rays at `targets` of one placed mesh, `count` of them, cycling through the target kinds.
pub(super) fn shoot_many(
    rng: &mut SceneRng,
    aimer: &Aimer<'_>,
    at: &Placement<'_>,
    targets: &[Target],
    shot: Shot,
    count: usize,
    case: &mut StressCase,
) {
    let mut attempts = 0;
    let goal = case.rays.len() + count;
    while case.rays.len() < goal && attempts < 8 * count + 16 {
        attempts += 1;
        let target = targets[rng.below(targets.len() as u64) as usize];
        let index = case.rays.len() as u32;
        if aimer.shoot(rng, target, at, shot, index, case).is_none() {
            case.rays.truncate(index as usize);
        }
    }
}

fn lattice_family(
    family: &str,
    seed: u64,
    size: usize,
    targets: &[Target],
    exponent: i32,
) -> StressCase {
    let mut rng = SceneRng(seed);
    let mesh = LatticeMesh::jittered_cube(&mut rng, 4);
    let mut case = cube_case(format!("{family}/{seed}"), &mesh, exponent);
    let members = single_geometry(&mesh);
    let at = Placement {
        instance: 0,
        exponent,
        object: &identity,
        world: &identity,
        members: &members,
    };
    shoot_many(
        &mut rng,
        &Aimer::new(&mesh),
        &at,
        targets,
        Shot::DEFAULT,
        size,
        &mut case,
    );
    case
}

/// Closed mesh, rays exactly through points `j/16` along shared edges.
pub fn watertight_edges(seed: u64, size: usize) -> StressCase {
    lattice_family("watertight-edges", seed, size, &[Target::Edge], -8)
}

/// Closed mesh, rays exactly through shared vertices.
pub fn watertight_vertices(seed: u64, size: usize) -> StressCase {
    lattice_family("watertight-vertices", seed, size, &[Target::Vertex], -8)
}

/// The closed mesh twice, far from the origin: once with the translation baked into the vertex
/// positions (+T), once at the origin behind an instance translation (−T); every f32 sum exact.
pub fn far_from_origin(seed: u64, size: usize) -> StressCase {
    let mut rng = SceneRng(seed);
    let mesh = LatticeMesh::jittered_cube(&mut rng, 4);
    let tau = 10f64.powf(rng.range(3.0, 7.0));
    // Granule 2^e: |±T| + the farthest origin (4640 units) below 2^23 units, so o ± T is exact.
    let exponent = (tau / 8.0e6).log2().ceil() as i32;
    let g = 2f64.powi(exponent);
    let t_units: [i64; 3] = [0, 1, 2].map(|_| {
        let mag = (tau * rng.range(0.5, 1.0) / g).round() as i64;
        if rng.below(2) == 0 {
            mag
        } else {
            -mag
        }
    });
    let neg = t_units.map(|x| -x);
    let offset = exact_point(t_units, exponent).expect("exact translation");
    let baked = mesh.positions(exponent, t_units).expect("exact far mesh");
    let base = mesh.positions(exponent, [0; 3]).expect("exact mesh");
    let ix = Some(mesh.indices.clone());
    let scene = Scene {
        bottom_levels: vec![
            BottomLevel {
                geometries: vec![geometry(baked, ix.clone(), None)],
            },
            BottomLevel {
                geometries: vec![geometry(base, ix, None)],
            },
        ],
        instances: vec![
            SceneInstance::of(0),
            SceneInstance {
                transform: Transform3x4::translation(exact_point(neg, exponent).expect("exact")),
                ..SceneInstance::of(1)
            },
        ],
    };
    let min_axis = t_units.iter().map(|x| x.abs()).min().unwrap_or(0) - mesh.extent();
    let min_distance = (min_axis as f64 * g) as f32;
    let mut case = StressCase {
        name: format!("far-from-origin/{seed}"),
        scene,
        rays: Vec::new(),
        claims: vec![
            Claim::ClosedMesh {
                bottom_level: 0,
                geometries: vec![0],
            },
            Claim::TranslatedCopy {
                copy: 0,
                base: 1,
                offset,
            },
            Claim::ExactTranslation { instance: 1 },
            Claim::FarFromOrigin {
                instance: 0,
                min_distance,
            },
            Claim::FarFromOrigin {
                instance: 1,
                min_distance,
            },
        ],
    };
    let members = single_geometry(&mesh);
    let aimer = Aimer::new(&mesh);
    let targets = [Target::Edge, Target::Vertex, Target::Interior];
    let plus = move |p: [i64; 3]| [0, 1, 2].map(|k| p[k] + t_units[k]);
    let minus = move |p: [i64; 3]| [0, 1, 2].map(|k| p[k] + neg[k]);
    let baked_at = Placement {
        instance: 0,
        exponent,
        object: &plus,
        world: &plus,
        members: &members,
    };
    let instanced_at = Placement {
        instance: 1,
        exponent,
        object: &identity,
        world: &minus,
        members: &members,
    };
    let half = size / 2;
    shoot_many(
        &mut rng,
        &aimer,
        &baked_at,
        &targets,
        Shot::DEFAULT,
        half,
        &mut case,
    );
    let rest = size - case.rays.len();
    shoot_many(
        &mut rng,
        &aimer,
        &instanced_at,
        &targets,
        Shot::DEFAULT,
        rest,
        &mut case,
    );
    case
}

/// The closed mesh scaled by `2^e`, e in [−76, 56]: coordinates from about 1e-20 to 1e20; half the
/// rays with directions scaled alike (t as at scale 1), half with integer directions.
pub fn extreme_scale(seed: u64, size: usize) -> StressCase {
    let mut rng = SceneRng(seed);
    let mesh = LatticeMesh::jittered_cube(&mut rng, 4);
    let exponent = -76 + rng.below(133) as i32;
    let mut case = cube_case(format!("extreme-scale/{seed}"), &mesh, exponent);
    let scale = 2f64.powi(exponent);
    case.claims.push(Claim::CoordinateRange {
        bottom_level: 0,
        min_abs: (LatticeMesh::STEP as f64 * scale) as f32,
        max_abs: (mesh.extent() as f64 * scale) as f32,
    });
    let members = single_geometry(&mesh);
    let at = Placement {
        instance: 0,
        exponent,
        object: &identity,
        world: &identity,
        members: &members,
    };
    let aimer = Aimer::new(&mesh);
    let targets = [Target::Edge, Target::Vertex, Target::Interior];
    shoot_many(
        &mut rng,
        &aimer,
        &at,
        &targets,
        Shot::DEFAULT,
        size / 2,
        &mut case,
    );
    let scaled = Shot {
        direction_exponent: exponent,
        ..Shot::DEFAULT
    };
    let rest = size - case.rays.len();
    shoot_many(&mut rng, &aimer, &at, &targets, scaled, rest, &mut case);
    case
}

/// A closed mesh of about `2000 · size` triangles (at most about 1e6), rays through its edges,
/// vertices and interiors, and as many camera rays.
pub fn large_mesh(seed: u64, size: usize) -> StressCase {
    let mut rng = SceneRng(seed);
    let triangles = (2000 * size).clamp(10_000, 1_030_000);
    let half = ((triangles as f64 / 48.0).sqrt().round() as u32).max(1);
    let mesh = LatticeMesh::jittered_cube(&mut rng, half);
    let exponent = -8;
    let mut case = cube_case(format!("large-mesh/{seed}"), &mesh, exponent);
    case.claims.push(Claim::MinTriangles {
        bottom_level: 0,
        count: (48 * half as u64 * half as u64),
    });
    let members = single_geometry(&mesh);
    let at = Placement {
        instance: 0,
        exponent,
        object: &identity,
        world: &identity,
        members: &members,
    };
    let aimer = Aimer::new(&mesh);
    let targets = [Target::Edge, Target::Vertex, Target::Interior];
    let exact = size.div_ceil(2);
    shoot_many(
        &mut rng,
        &aimer,
        &at,
        &targets,
        Shot::DEFAULT,
        exact,
        &mut case,
    );
    // Camera rays from outside the cube toward its centre.
    let r = mesh.extent() as f64 * 2f64.powi(exponent);
    let eye = [2.2 * r, -1.7 * r, 1.9 * r];
    let side = ((size - exact.min(size)) as f64).sqrt().ceil() as u32;
    let cam = pinhole_rays(side, side, eye, [0.0; 3], [0.0, 0.0, 1.0], 0.6);
    case.rays
        .extend(cam.into_iter().take(size - case.rays.len().min(size)));
    case
}
