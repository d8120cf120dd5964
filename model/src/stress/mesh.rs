//! An exact closed mesh for the stress families: the surface of a cube cut into cells, each vertex
//! jittered, every coordinate an integer number of granules — so scaling by a power of two,
//! translating by a multiple of the granule, and aiming rays through its edges and vertices stay
//! exact in f32.

use crate::scene::build::SceneRng;
use std::collections::HashMap;

/// A closed, consistently wound, indexed triangle mesh in integer units ("granules").
#[derive(Debug, Clone, PartialEq)]
pub struct LatticeMesh {
    /// Vertex coordinates in granules; every coordinate is a multiple of [`LatticeMesh::STEP`].
    pub units: Vec<[i64; 3]>,
    /// Three vertex indices per triangle, wound counter-clockwise seen from outside.
    pub indices: Vec<u32>,
    /// The cube face of each triangle: `2 · axis + (1 if the face looks toward +axis)`.
    pub faces: Vec<u8>,
}

/// An edge shared by two triangles: `from → to` in `first`, `to → from` in `second`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SharedEdge {
    pub first: usize,
    pub second: usize,
    pub from: usize,
    pub to: usize,
}

impl LatticeMesh {
    /// The side of one cell, in granules.
    pub const CELL: i64 = 256;
    /// The jitter step: every vertex coordinate is a multiple of it, so a point `j/16` of the
    /// way along an edge is an integer number of granules.
    pub const STEP: i64 = 16;

    /// The surface of the cube `[−half, half]³` (in cells), `2·half` cells along each face's side,
    /// two triangles per cell with the diagonal drawn at random, every vertex moved by up to an
    /// eighth of a cell along each axis: `48·half²` triangles, closed (every edge shared by exactly
    /// two triangles, in opposite directions).
    pub fn jittered_cube(rng: &mut SceneRng, half: u32) -> LatticeMesh {
        let h = half as i64;
        let mut index: HashMap<[i64; 3], u32> = HashMap::new();
        let mut units: Vec<[i64; 3]> = Vec::new();
        let jitter = Self::CELL / 8 / Self::STEP;
        let mut vertex = |lattice: [i64; 3], rng: &mut SceneRng| -> u32 {
            *index.entry(lattice).or_insert_with(|| {
                let p = lattice.map(|x| {
                    let j = rng.below((2 * jitter + 1) as u64) as i64 - jitter;
                    x * Self::CELL + j * Self::STEP
                });
                units.push(p);
                (units.len() - 1) as u32
            })
        };
        let mut indices = Vec::new();
        let mut faces = Vec::new();
        for axis in 0..3 {
            for positive in [false, true] {
                // In-face axes (b, c) with e_b × e_c = e_axis.
                let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
                for u in -h..h {
                    for v in -h..h {
                        let at = |du: i64, dv: i64| {
                            let mut p = [0i64; 3];
                            p[axis] = if positive { h } else { -h };
                            p[b] = u + du;
                            p[c] = v + dv;
                            p
                        };
                        let mut quad = [at(0, 0), at(1, 0), at(1, 1), at(0, 1)];
                        if !positive {
                            quad.reverse();
                        }
                        let q = quad.map(|p| vertex(p, rng));
                        let tris = if rng.below(2) == 0 {
                            [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
                        } else {
                            [[q[0], q[1], q[3]], [q[1], q[2], q[3]]]
                        };
                        for t in tris {
                            indices.extend(t);
                            faces.push((2 * axis + positive as usize) as u8);
                        }
                    }
                }
            }
        }
        LatticeMesh {
            units,
            indices,
            faces,
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// The vertex indices of triangle `p`.
    pub fn triangle(&self, p: usize) -> [usize; 3] {
        [0, 1, 2].map(|k| self.indices[3 * p + k] as usize)
    }

    /// The largest coordinate magnitude, in granules.
    pub fn extent(&self) -> i64 {
        self.units
            .iter()
            .flatten()
            .map(|x| x.abs())
            .max()
            .unwrap_or(0)
    }

    /// Every shared edge once.
    pub fn shared_edges(&self) -> Vec<SharedEdge> {
        let mut directed: HashMap<(usize, usize), usize> = HashMap::new();
        for p in 0..self.triangle_count() {
            let t = self.triangle(p);
            for k in 0..3 {
                directed.insert((t[k], t[(k + 1) % 3]), p);
            }
        }
        let mut out: Vec<SharedEdge> = directed
            .iter()
            .filter(|((a, b), _)| a < b)
            .filter_map(|(&(a, b), &first)| {
                directed.get(&(b, a)).map(|&second| SharedEdge {
                    first,
                    second,
                    from: a,
                    to: b,
                })
            })
            .collect();
        out.sort_by_key(|e| (e.from, e.to));
        out
    }

    /// The triangles around each vertex.
    pub fn fans(&self) -> Vec<Vec<usize>> {
        let mut fans = vec![Vec::new(); self.units.len()];
        for p in 0..self.triangle_count() {
            for v in self.triangle(p) {
                fans[v].push(p);
            }
        }
        fans
    }

    /// The positions `(units + offset) · 2^exponent` in f32; `None` unless every one is exact.
    pub fn positions(&self, exponent: i32, offset: [i64; 3]) -> Option<Vec<[f32; 3]>> {
        self.units
            .iter()
            .map(|p| exact_point([0, 1, 2].map(|k| p[k] + offset[k]), exponent))
            .collect()
    }
}

/// `x · 2^exponent` as an f32, when exact and normal (or zero).
pub fn exact_f32(x: i64, exponent: i32) -> Option<f32> {
    let v = x as f64 * 2f64.powi(exponent);
    if x.unsigned_abs() >= 1 << 53 {
        return None;
    }
    let f = v as f32;
    let normal = f == 0.0 || f.is_normal();
    (normal && f as f64 == v).then_some(f)
}

/// A point of integer units scaled by `2^exponent`, when every coordinate is exact in f32.
pub fn exact_point(p: [i64; 3], exponent: i32) -> Option<[f32; 3]> {
    Some([
        exact_f32(p[0], exponent)?,
        exact_f32(p[1], exponent)?,
        exact_f32(p[2], exponent)?,
    ])
}
