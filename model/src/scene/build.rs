//! Deterministic scene builders for the generator, the tests and the benchmarks: triangle soups,
//! closed meshes (subdivided icosahedra, grids, fans), instanced copies, boxes with spheres,
//! pinhole camera rays, and rays aimed exactly at shared edges and vertices.

use super::{
    Aabb, Aabbs, BottomLevel, Geometry, GeometryData, GeometryFlags, Indices, Ray, SceneInstance,
    Sphere, Transform3x4, Triangles,
};

/// A small deterministic generator (SplitMix64), so builders need no dependency and never change
/// their output across versions.
#[derive(Debug, Clone)]
pub struct SceneRng(pub u64);

impl SceneRng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    /// Uniform integer in [0, n).
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n.max(1)
    }
    /// A multiple of 2^-bits in [lo, hi): an exact binary fraction.
    pub fn fraction(&mut self, lo: f64, hi: f64, bits: u32) -> f32 {
        let scale = (1u64 << bits) as f64;
        ((self.range(lo, hi) * scale).floor() / scale) as f32
    }
    pub fn point(&mut self, lo: f64, hi: f64) -> [f32; 3] {
        [0, 1, 2].map(|_| self.range(lo, hi) as f32)
    }
}

fn triangles(positions: Vec<[f32; 3]>, indices: Option<Vec<u32>>, opaque: bool) -> Geometry {
    let indices = indices.map(|ix| {
        if ix.iter().all(|&i| i <= u16::MAX as u32) {
            Indices::U16(ix.iter().map(|&i| i as u16).collect())
        } else {
            Indices::U32(ix)
        }
    });
    Geometry {
        flags: GeometryFlags {
            opaque,
            no_duplicate_any_hit: false,
        },
        data: GeometryData::Triangles(Triangles {
            positions,
            indices,
            transform: None,
        }),
    }
}

/// One geometry of `count` random triangles in the cube [-extent, extent]³, non-indexed; each
/// triangle's size is at most `size`.
pub fn triangle_soup(seed: u64, count: usize, extent: f64, size: f64) -> BottomLevel {
    let mut rng = SceneRng(seed);
    let mut positions = Vec::with_capacity(3 * count);
    for _ in 0..count {
        let c = rng.point(-extent, extent);
        for _ in 0..3 {
            let p = [0, 1, 2].map(|k| (c[k] as f64 + rng.range(-size, size)) as f32);
            positions.push(p);
        }
    }
    BottomLevel {
        geometries: vec![triangles(positions, None, true)],
    }
}

/// A closed, indexed sphere mesh: an icosahedron subdivided `subdivisions` times (20·4^s triangles),
/// wound counter-clockwise seen from outside (front faces outward).
pub fn icosphere(subdivisions: u32, radius: f64) -> BottomLevel {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut verts: Vec<[f64; 3]> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let mut faces: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::with_capacity(faces.len() * 4);
        let mut midpoint = |a: u32, b: u32, verts: &mut Vec<[f64; 3]>| -> u32 {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (verts[a as usize], verts[b as usize]);
                verts.push([0, 1, 2].map(|k| 0.5 * (p[k] + q[k])));
                (verts.len() - 1) as u32
            })
        };
        for f in &faces {
            let a = midpoint(f[0], f[1], &mut verts);
            let b = midpoint(f[1], f[2], &mut verts);
            let c = midpoint(f[2], f[0], &mut verts);
            next.extend([[f[0], a, c], [f[1], b, a], [f[2], c, b], [a, b, c]]);
        }
        faces = next;
    }
    let positions = verts
        .iter()
        .map(|v| {
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            v.map(|x| (x / n * radius) as f32)
        })
        .collect();
    BottomLevel {
        geometries: vec![triangles(positions, Some(faces.concat()), true)],
    }
}

/// A closed-fan-rich indexed grid of `nx`×`ny` cells in the plane z = 0, from (0,0) with cells of
/// `cell` (a power of two keeps every vertex, edge midpoint and centre an exact binary fraction);
/// two triangles per cell, wound counter-clockwise seen from +z, so front-facing for rays going −z
/// (spec, "Ray Face Culling": `d·((v1 − v0) × (v2 − v0)) < 0` is front).
pub fn grid(nx: u32, ny: u32, cell: f32) -> BottomLevel {
    let mut positions = Vec::with_capacity(((nx + 1) * (ny + 1)) as usize);
    for j in 0..=ny {
        for i in 0..=nx {
            positions.push([i as f32 * cell, j as f32 * cell, 0.0]);
        }
    }
    let at = |i: u32, j: u32| j * (nx + 1) + i;
    let mut indices = Vec::with_capacity((nx * ny * 6) as usize);
    for j in 0..ny {
        for i in 0..nx {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            indices.extend([a, b, c, a, c, d]);
        }
    }
    BottomLevel {
        geometries: vec![triangles(positions, Some(indices), true)],
    }
}

/// A closed fan of `n` triangles around the origin in the plane z = 0 (every edge at the centre
/// shared by exactly two triangles), ring radius `radius`, wound counter-clockwise seen from +z.
pub fn fan(n: u32, radius: f64) -> BottomLevel {
    let mut positions = vec![[0.0f32; 3]];
    for k in 0..n {
        let a = std::f64::consts::TAU * k as f64 / n as f64;
        positions.push([(radius * a.cos()) as f32, (radius * a.sin()) as f32, 0.0]);
    }
    let mut indices = Vec::new();
    for k in 0..n {
        indices.extend([0, 1 + k, 1 + (k + 1) % n]);
    }
    BottomLevel {
        geometries: vec![triangles(positions, Some(indices), true)],
    }
}

/// Boxes with spheres inside: `count` spheres of radius up to `size` in [-extent, extent]³, each in
/// a box enlarged by up to `size` beyond the sphere.
pub fn spheres_in_boxes(seed: u64, count: usize, extent: f64, size: f64) -> BottomLevel {
    let mut rng = SceneRng(seed);
    let mut boxes = Vec::new();
    let mut spheres = Vec::new();
    for _ in 0..count {
        let center = rng.point(-extent, extent);
        let radius = rng.range(0.2 * size, size) as f32;
        let grow = [0, 1, 2].map(|_| rng.range(0.0, size));
        let min = [0, 1, 2]
            .map(|k| ((center[k] as f64 - radius as f64 - grow[k]) as f32).min(center[k] - radius));
        let max = [0, 1, 2]
            .map(|k| ((center[k] as f64 + radius as f64 + grow[k]) as f32).max(center[k] + radius));
        // Guard f32 rounding: the sphere must stay inside its box.
        let min =
            [0, 1, 2].map(|k| min[k].min(((center[k] as f64) - radius as f64).next_down_f32()));
        let max = [0, 1, 2].map(|k| max[k].max(((center[k] as f64) + radius as f64).next_up_f32()));
        boxes.push(Aabb { min, max });
        spheres.push(Sphere { center, radius });
    }
    BottomLevel {
        geometries: vec![Geometry {
            flags: GeometryFlags {
                opaque: true,
                no_duplicate_any_hit: false,
            },
            data: GeometryData::Aabbs(Aabbs { boxes, spheres }),
        }],
    }
}

trait RoundF32 {
    fn next_down_f32(self) -> f32;
    fn next_up_f32(self) -> f32;
}

impl RoundF32 for f64 {
    /// The largest f32 not above self.
    fn next_down_f32(self) -> f32 {
        let f = self as f32;
        if (f as f64) > self {
            f32::from_bits(if f > 0.0 {
                f.to_bits() - 1
            } else {
                f.to_bits() + 1
            })
        } else {
            f
        }
    }
    /// The smallest f32 not below self.
    fn next_up_f32(self) -> f32 {
        -(-self).next_down_f32()
    }
}

/// The rotation about a unit axis by `angle` radians, then uniform `scale`, then `translation`;
/// `mirror` negates X first.
pub fn similarity(
    axis: [f64; 3],
    angle: f64,
    scale: f64,
    mirror: bool,
    translation: [f64; 3],
) -> Transform3x4 {
    let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let [x, y, z] = axis.map(|a| a / n);
    let (s, c) = angle.sin_cos();
    let r = [
        [
            c + x * x * (1.0 - c),
            x * y * (1.0 - c) - z * s,
            x * z * (1.0 - c) + y * s,
        ],
        [
            y * x * (1.0 - c) + z * s,
            c + y * y * (1.0 - c),
            y * z * (1.0 - c) - x * s,
        ],
        [
            z * x * (1.0 - c) - y * s,
            z * y * (1.0 - c) + x * s,
            c + z * z * (1.0 - c),
        ],
    ];
    let m = if mirror { -1.0 } else { 1.0 };
    Transform3x4([0, 1, 2].map(|row| {
        [
            (r[row][0] * scale * m) as f32,
            (r[row][1] * scale) as f32,
            (r[row][2] * scale) as f32,
            translation[row] as f32,
        ]
    }))
}

/// `count` instances of bottom level `bottom_level` with random rotations, scales in
/// [0.5, 2], every third one mirrored, translated within [-spread, spread]³.
pub fn instanced_copies(
    seed: u64,
    bottom_level: u32,
    count: usize,
    spread: f64,
) -> Vec<SceneInstance> {
    let mut rng = SceneRng(seed);
    (0..count)
        .map(|i| {
            let axis = [
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(0.1, 1.0),
            ];
            let t = [0, 1, 2].map(|_| rng.range(-spread, spread));
            SceneInstance {
                transform: similarity(
                    axis,
                    rng.range(0.0, std::f64::consts::TAU),
                    rng.range(0.5, 2.0),
                    i % 3 == 2,
                    t,
                ),
                custom_index: i as u32,
                ..SceneInstance::of(bottom_level)
            }
        })
        .collect()
}

/// Pinhole camera rays for a `width`×`height` launch (x fastest), through pixel centres.
pub fn pinhole_rays(
    width: u32,
    height: u32,
    eye: [f64; 3],
    target: [f64; 3],
    up: [f64; 3],
    fov_y: f64,
) -> Vec<Ray> {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let norm = |a: [f64; 3]| {
        let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        a.map(|x| x / n)
    };
    let f = norm(sub(target, eye));
    let r = norm(cross(f, up));
    let u = cross(r, f);
    let h = (fov_y / 2.0).tan();
    let aspect = width as f64 / height as f64;
    let mut rays = Vec::with_capacity((width * height) as usize);
    for j in 0..height {
        for i in 0..width {
            let x = (2.0 * (i as f64 + 0.5) / width as f64 - 1.0) * h * aspect;
            let y = (1.0 - 2.0 * (j as f64 + 0.5) / height as f64) * h;
            let d = [0, 1, 2].map(|k| (f[k] + x * r[k] + y * u[k]) as f32);
            rays.push(Ray::new(eye.map(|x| x as f32), d, 0.0, f32::INFINITY));
        }
    }
    rays
}

/// Rays straight down (−z) onto world points, from `height` above them: with binary-fraction
/// points and a power-of-two height, origin and hit point are exact.
pub fn rays_down_onto(points: &[[f32; 3]], height: f32) -> Vec<Ray> {
    points
        .iter()
        .map(|p| {
            Ray::new(
                [p[0], p[1], p[2] + height],
                [0.0, 0.0, -1.0],
                0.0,
                f32::INFINITY,
            )
        })
        .collect()
}

/// Exact binary-fraction points of a [`grid`]: midpoints of its interior shared edges (the
/// horizontal, vertical and diagonal ones) and its interior vertices.
pub fn grid_shared_points(nx: u32, ny: u32, cell: f32) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let mut edges = Vec::new();
    let mut vertices = Vec::new();
    let c = cell;
    for j in 0..ny {
        for i in 0..nx {
            let (x, y) = (i as f32 * c, j as f32 * c);
            // The cell's diagonal, shared by its two triangles.
            edges.push([x + 0.5 * c, y + 0.5 * c, 0.0]);
            if i > 0 {
                edges.push([x, y + 0.5 * c, 0.0]);
            }
            if j > 0 {
                edges.push([x + 0.5 * c, y, 0.0]);
            }
            if i > 0 && j > 0 {
                vertices.push([x, y, 0.0]);
            }
        }
    }
    (edges, vertices)
}
