//! Rays aimed exactly: a target point of a [`LatticeMesh`] (a point on a shared edge, a vertex, an
//! interior point), an integer direction, and the origin `target − distance · direction`, all in
//! integer granules, turned into f32 rays only when every value is exact.

use super::mesh::{exact_point, LatticeMesh};
use crate::scene::build::SceneRng;
use crate::scene::Ray;

/// A random direction with integer components in `[−max, max]`, not all zero.
pub fn direction(rng: &mut SceneRng, max: i64) -> [i64; 3] {
    loop {
        let d = [0, 1, 2].map(|_| rng.below((2 * max + 1) as u64) as i64 - max);
        if d != [0, 0, 0] {
            return d;
        }
    }
}

/// An interior point of a triangle whose coordinates are multiples of [`LatticeMesh::STEP`]:
/// weights `w/16` of at least 3/16 on each vertex.
pub fn interior_point(rng: &mut SceneRng, v: [[i64; 3]; 3]) -> [i64; 3] {
    let w0 = 3 + rng.below(8) as i64;
    let w1 = 3 + rng.below((11 - w0) as u64) as i64;
    let w = [w0, w1, 16 - w0 - w1];
    [0, 1, 2].map(|k| (w[0] * v[0][k] + w[1] * v[1][k] + w[2] * v[2][k]) / LatticeMesh::STEP)
}

/// `target − distance · direction`.
pub fn origin(target: [i64; 3], direction: [i64; 3], distance: i64) -> [i64; 3] {
    [0, 1, 2].map(|k| target[k] - distance * direction[k])
}

/// The ray from `origin` (granules scaled by `2^exponent`) along `direction` (scaled by
/// `2^direction_exponent`), when both are exact in f32.
pub fn exact_ray(
    origin: [i64; 3],
    exponent: i32,
    direction: [i64; 3],
    direction_exponent: i32,
    tmax: f32,
) -> Option<Ray> {
    Some(Ray::new(
        exact_point(origin, exponent)?,
        exact_point(direction, direction_exponent)?,
        0.0,
        tmax,
    ))
}
