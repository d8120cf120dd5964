//! A scene made ready for tracing: world-space vertices (f64 with error bounds) per instance and
//! geometry, ray-independent error radii, and a BVH over world-space primitive boxes whose culling
//! is conservative against the band (a node is skipped only when its padded box is missed, and the
//! pad of a node dominates the pads of everything below it, so the BVH skips exactly the
//! primitives the per-primitive far test would reject).

use super::arith::{affine, v3, BoundedF64};
use super::band::{
    far_pad_scale, far_pad_scaled, norm3, vertex_static_radius, InstanceBand, BAND_SAFETY_FACTOR,
    SPHERE_SHADER_ERROR,
};
use super::bvh::{build_bvh, WideTree};
use super::pages::PageBacked;
use crate::scene::{Aabb, GeometryData, Problem, Scene, Sphere, Transform3x4};
use std::collections::HashMap;
use std::sync::OnceLock;

/// Which kind of primitive a prepared geometry holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PrimitiveKind {
    Triangle,
    Aabb,
}

/// One geometry of one instance, in world space.
#[derive(Debug)]
pub(crate) struct WorldGeometry {
    pub instance: u32,
    pub geometry: u32,
    pub bottom_level: u32,
    pub kind: PrimitiveKind,
    /// Triangles: where the geometry's world vertices with their static radii start in the
    /// scene's array ([`PreparedScene::world_vertex`]), and how many there are (its vertex
    /// order; none for boxes).
    pub first_vertex: usize,
    pub vertex_count: usize,
    /// Triangles: the identity class of the geometry transform within the bottom level.
    pub transform_class: u32,
}

/// One instance, with its band.
#[derive(Debug)]
pub(crate) struct PreparedInstance {
    pub band: InstanceBand,
    /// Sign of det(A): a mirroring instance flips world normals against object normals.
    pub det_negative: bool,
    /// Both the instance and (per geometry) the geometry transform are exact identities.
    pub identity: bool,
}

/// A world-space box with everything needed to pad it for a ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FarBox {
    pub lo: [f64; 3],
    pub hi: [f64; 3],
    pub static_pad: f64,
    pub rel: f64,
    pub origin_coef: f64,
    pub norm_t: f64,
    /// `1 / (1 − 2·rel)` rounded up (see `band::far_pad`); infinite where `rel ≥ 1/4`.
    pub inv_den: f64,
    /// A pad at least [`ItemFar::is_far`]'s for every ray: `pad_base + pad_slope·|o|` (the pad of
    /// [`BoundBox::entry`]).
    pub pad_base: f64,
    pub pad_slope: f64,
}

impl FarBox {
    /// A box with its pad constants.
    pub fn new(
        lo: [f64; 3],
        hi: [f64; 3],
        static_pad: f64,
        rel: f64,
        origin_coef: f64,
        norm_t: f64,
    ) -> FarBox {
        let inv_den = far_pad_scale(rel);
        // The farthest point of the box from the world origin: |o − x| ≤ |o| + reach for every
        // point x of it, so `m` of `ItemFar::is_far` is at most |o| + reach.
        let reach = (0..3)
            .map(|k| {
                let x = lo[k].abs().max(hi[k].abs());
                x * x
            })
            .sum::<f64>()
            .sqrt()
            * BOUND_SLACK;
        // `far_pad_scaled` is affine and increasing in `origin_radius` and `max_distance`; with
        // `origin_radius = origin_coef·(|o| + norm_t)` and `max_distance ≤ |o| + reach` it is
        // below `pad_base + pad_slope·|o|`, and BOUND_SLACK covers the rounding of both sides.
        let pad_base =
            far_pad_scaled(static_pad, rel, inv_den, origin_coef * norm_t, reach) * BOUND_SLACK;
        let pad_slope = far_pad_scaled(0.0, rel, inv_den, origin_coef, 1.0) * BOUND_SLACK;
        FarBox {
            lo,
            hi,
            static_pad,
            rel,
            origin_coef,
            norm_t,
            inv_den,
            pad_base,
            pad_slope,
        }
    }

    /// [`ItemFar::entry`] of this box uncompacted.
    pub(crate) fn entry(&self, ray: &RayF64) -> Option<FarEntry> {
        far_entry(
            ray,
            &self.lo,
            &self.hi,
            self.static_pad,
            &FarConstants::of(self),
        )
    }

    pub(crate) fn union(&self, o: &FarBox) -> FarBox {
        FarBox::new(
            [0, 1, 2].map(|k| self.lo[k].min(o.lo[k])),
            [0, 1, 2].map(|k| self.hi[k].max(o.hi[k])),
            self.static_pad.max(o.static_pad),
            self.rel.max(o.rel),
            self.origin_coef.max(o.origin_coef),
            self.norm_t.max(o.norm_t),
        )
    }
}

/// The constants of a far box's pad that the items of one instance band share (see
/// [`ItemFar`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FarConstants {
    rel: f64,
    inv_den: f64,
    origin_coef: f64,
    norm_t: f64,
}

impl FarConstants {
    fn of(b: &FarBox) -> FarConstants {
        FarConstants {
            rel: b.rel,
            inv_den: b.inv_den,
            origin_coef: b.origin_coef,
            norm_t: b.norm_t,
        }
    }

    /// The bits the constants are shared by (identical bits, identical pads).
    fn key(&self) -> [u64; 4] {
        [self.rel, self.inv_den, self.origin_coef, self.norm_t].map(f64::to_bits)
    }
}

/// What [`ItemFar::is_far`] reads of an item, in one cache line: its box and static pad, and the
/// index of its other pad constants in [`PreparedScene::far_constants`] (a few per scene). The
/// far test of an item the walk reaches touches this line alone.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
pub(crate) struct ItemFar {
    lo: [f64; 3],
    hi: [f64; 3],
    static_pad: f64,
    constants: u32,
}

const _: () = assert!(
    std::mem::size_of::<ItemFar>() == 64,
    "an item's far test reads one cache line"
);

impl ItemFar {
    /// Whether the ray segment misses the item's padded far box: then no conformant implementation can
    /// report a hit on anything inside (see `band::far_pad`, whose pad this evaluates with the
    /// division by `1 − 2·rel` done as a multiplication by its reciprocal rounded up, and the slab
    /// divisions as multiplications by the ray's reciprocal directions: both within the f64 slack
    /// `far_pad` adds for the slab test). Monotone under box containment.
    /// `constants` are the scene's shared pad constants.
    #[inline]
    pub fn is_far(&self, ray: &RayF64, constants: &[FarConstants]) -> bool {
        self.entry(ray, constants).is_none()
    }

    /// [`ItemFar::is_far`] as None, or where the segment meets the padded box, its [`FarEntry`]:
    /// what the same test with a lower `tmax` answers without being run again.
    #[inline]
    pub fn entry(&self, ray: &RayF64, constants: &[FarConstants]) -> Option<FarEntry> {
        far_entry(
            ray,
            &self.lo,
            &self.hi,
            self.static_pad,
            &constants[self.constants as usize],
        )
    }
}

/// Where a ray's segment meets an item's padded far box, as the far test found it: `t` is the entry
/// t of the padded box where `exact`, else that of the box without its pad (the test's first
/// step), which is at least the padded box's (the slab bounds are monotone in the box). The test of
/// the same ray with `tmax` lowered to `c` meets the box the entry is of exactly where `t ≤ c`: the
/// slab values do not depend on `tmax`, and the segment met that box's slabs at the higher `tmax`.
/// So `t ≤ c` is never far; `t > c` is far where `exact`, and decides nothing otherwise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FarEntry {
    pub t: f64,
    pub exact: bool,
}

impl FarEntry {
    /// An entry that decides nothing: every lower `tmax` runs the test again.
    pub const UNKNOWN: FarEntry = FarEntry {
        t: f64::INFINITY,
        exact: false,
    };

    /// Whether [`ItemFar::is_far`] holds for the ray cut at `c` (at most the `tmax` this entry was
    /// found at); `test` runs it where the entry alone cannot say.
    #[inline]
    pub fn far_at(&self, c: f64, test: impl FnOnce() -> bool) -> bool {
        if self.t <= c {
            false
        } else {
            self.exact || test()
        }
    }
}

/// The far boxes in their one-line form, with the constants they share.
pub(crate) fn compact_far_boxes(boxes: &[FarBox]) -> (Vec<ItemFar>, Vec<FarConstants>) {
    let mut constants: Vec<FarConstants> = Vec::new();
    let mut index: HashMap<[u64; 4], u32> = HashMap::new();
    let items = boxes
        .iter()
        .map(|b| {
            let c = FarConstants::of(b);
            let k = *index.entry(c.key()).or_insert_with(|| {
                constants.push(c);
                constants.len() as u32 - 1
            });
            ItemFar {
                lo: b.lo,
                hi: b.hi,
                static_pad: b.static_pad,
                constants: k,
            }
        })
        .collect();
    (items, constants)
}

/// Whether the ray segment misses the box `[lo, hi]` grown by its pad for this ray (the test of
/// [`ItemFar::is_far`]; the arguments are a [`FarBox`]'s fields).
#[inline]
fn far_entry(
    ray: &RayF64,
    lo: &[f64; 3],
    hi: &[f64; 3],
    static_pad: f64,
    c: &FarConstants,
) -> Option<FarEntry> {
    // A segment that meets the box itself meets it padded (the pad is never negative, and
    // the rounded slab bounds are monotone in it): not far, without the pad.
    if let Some(t) = slab_entry(ray, *lo, *hi) {
        return Some(FarEntry { t, exact: false });
    }
    let o = &ray.origin;
    let axis = |k: usize| {
        let x = (lo[k] - o[k]).abs().max((hi[k] - o[k]).abs());
        x * x
    };
    let m = (axis(0) + axis(1) + axis(2)).sqrt();
    let r_o = c.origin_coef * (ray.origin_norm + c.norm_t);
    let pad = far_pad_scaled(static_pad, c.rel, c.inv_den, r_o, m);
    if !pad.is_finite() {
        // Never far, whatever the segment.
        return Some(FarEntry {
            t: f64::NEG_INFINITY,
            exact: true,
        });
    }
    slab_entry(ray, lo.map(|v| v - pad), hi.map(|v| v + pad)).map(|t| FarEntry { t, exact: true })
}

/// The slab test in f64: where the ray's segment [tmin, tmax] meets the box [lo, hi], its entry t
/// (an axis the ray does not move along decides by the origin alone); None where it misses.
#[inline]
#[allow(clippy::needless_range_loop)] // four arrays indexed by one axis
fn slab_entry(ray: &RayF64, lo: [f64; 3], hi: [f64; 3]) -> Option<f64> {
    if ray.oblique {
        return oblique_slab_entry(ray, lo, hi, ray.tmax);
    }
    let o = &ray.origin;
    let mut near = ray.tmin;
    let mut far = ray.tmax;
    for k in 0..3 {
        if ray.direction[k] == 0.0 {
            if o[k] < lo[k] || o[k] > hi[k] {
                return None;
            }
        } else {
            let inv = ray.inv_direction[k];
            let t1 = (lo[k] - o[k]) * inv;
            let t2 = (hi[k] - o[k]) * inv;
            near = near.max(t1.min(t2));
            far = far.min(t1.max(t2));
        }
    }
    (near <= far).then_some(near)
}

/// The slab test of a ray none of whose direction components is 0, over `[tmin, tmax]`: the entry t
/// into `[lo, hi]`, or None where the segment misses it. The slab bounds are then finite or
/// infinite, never NaN (finite origin, boxes never +inf below or -inf above), so the comparisons
/// are `max`/`min` and the sign of the reciprocal says which face comes first: the same values as
/// the test that orders each axis's two bounds.
#[inline(always)]
fn oblique_slab_entry(ray: &RayF64, lo: [f64; 3], hi: [f64; 3], tmax: f64) -> Option<f64> {
    let o = &ray.origin;
    let mut near = ray.tmin;
    let mut far = tmax;
    for k in 0..3 {
        let inv = ray.inv_direction[k];
        let (first, last) = if inv > 0.0 {
            (lo[k], hi[k])
        } else {
            (hi[k], lo[k])
        };
        let t_in = (first - o[k]) * inv;
        let t_out = (last - o[k]) * inv;
        near = if t_in > near { t_in } else { near };
        far = if t_out < far { t_out } else { far };
    }
    (near <= far).then_some(near)
}

/// The traversal's compact copy of a [`FarBox`]: its corners rounded outward to f32 and its pad
/// bounded by `pad_base + pad_slope·|o|` (coefficients rounded up), so the box it tests contains
/// the f64 one and its pad is at least [`ItemFar::is_far`]'s. The slab test is evaluated in f64
/// either way and its rounded bounds are monotone in the box and the pad, so a miss here is a miss
/// there. A quarter of the bytes of the FarBox, and no square root.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BoundBox {
    pub lo: [f32; 3],
    pub hi: [f32; 3],
    pub pad_base: f32,
    pub pad_slope: f32,
}

/// The greatest f32 at most `x` (NaN stays NaN). The step below is found whatever the rounding and
/// taken by a mask where the nearest f32 lies above `x`, not by a branch on it: the walk rounds each
/// ray's cut with it at every node, where that is a coin toss (the sign, which sets the step's
/// direction, is the same for every cut).
#[inline]
pub(crate) fn f32_down(x: f64) -> f32 {
    let y = x as f32;
    let bits = y.to_bits();
    // The next f32 below `y`: one step towards zero for a positive `y`, else (either zero or a
    // negative `y`) one step away from zero on the negative side; +inf steps to f32::MAX.
    let below = if (bits as i32) > 0 {
        bits.wrapping_sub(1)
    } else {
        (bits | 0x8000_0000).wrapping_add(1)
    };
    // All ones where `y` rounded up (never for a NaN, whose comparison is false).
    let above = u32::from((y as f64) > x).wrapping_neg();
    f32::from_bits((below & above) | (bits & !above))
}

/// The least f32 at least `x`.
pub(crate) fn f32_up(x: f64) -> f32 {
    -f32_down(-x)
}

impl BoundBox {
    pub fn of(b: &FarBox) -> BoundBox {
        BoundBox {
            lo: b.lo.map(f32_down),
            hi: b.hi.map(f32_up),
            pad_base: f32_up(b.pad_base),
            pad_slope: f32_up(b.pad_slope),
        }
    }

    /// The ray's entry t into the padded box over `[tmin, tmax]`, or None when it misses it
    /// (then [`ItemFar::is_far`] holds at the same `tmax`); an entry t above a lower `tmax` is a
    /// miss at that `tmax`.
    #[inline]
    #[allow(clippy::needless_range_loop)] // four arrays indexed by one axis
    pub fn entry(&self, ray: &RayF64, tmax: f64) -> Option<f64> {
        let o = &ray.origin;
        let pad = self.pad_base as f64 + self.pad_slope as f64 * ray.origin_norm;
        // An infinite (or NaN) pad is never a miss, as in `is_far`.
        if pad.is_nan() || pad == f64::INFINITY {
            return Some(f64::NEG_INFINITY);
        }
        if ray.oblique {
            return oblique_slab_entry(
                ray,
                self.lo.map(|x| x as f64 - pad),
                self.hi.map(|x| x as f64 + pad),
                tmax,
            );
        }
        let mut near = ray.tmin;
        let mut far = tmax;
        {
            for k in 0..3 {
                let lo = self.lo[k] as f64 - pad;
                let hi = self.hi[k] as f64 + pad;
                if ray.direction[k] == 0.0 {
                    if o[k] < lo || o[k] > hi {
                        return None;
                    }
                } else {
                    let inv = ray.inv_direction[k];
                    let t1 = (lo - o[k]) * inv;
                    let t2 = (hi - o[k]) * inv;
                    near = near.max(t1.min(t2));
                    far = far.min(t1.max(t2));
                }
            }
        }
        if near > far {
            None
        } else {
            Some(near)
        }
    }
}

/// A ray in f64 (exact conversions).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct RayF64 {
    pub origin: [f64; 3],
    pub direction: [f64; 3],
    pub tmin: f64,
    pub tmax: f64,
    pub origin_norm: f64,
    /// `norm3(direction)`, made once for the ray's pairs.
    pub direction_norm: f64,
    /// `1 / direction` per axis (0 where the direction is 0, which the slab test handles apart).
    pub inv_direction: [f64; 3],
    /// No direction component is 0.
    pub oblique: bool,
    /// Every triangle of the scene keeps an f32 test of this ray in range
    /// ([`PreparedScene::in_f32_range`]); false until that is known, and each pair is asked.
    pub in_f32_range: bool,
}

impl RayF64 {
    pub fn of(ray: &crate::scene::Ray) -> RayF64 {
        let origin = ray.origin.map(|x| x as f64);
        let direction = ray.direction.map(|x| x as f64);
        RayF64 {
            origin,
            direction,
            inv_direction: direction.map(|d| if d == 0.0 { 0.0 } else { 1.0 / d }),
            oblique: direction.iter().all(|&d| d != 0.0),
            tmin: ray.tmin as f64,
            tmax: ray.tmax as f64,
            origin_norm: norm3(origin),
            direction_norm: norm3(direction),
            in_f32_range: false,
        }
    }
}

/// A primitive in the BVH: geometry (index into `geometries`) and primitive index, and a
/// triangle's vertex indices (read from its index buffer once, here; zero for an AABB) and whether
/// two of its vertices coincide (in object space, so for every ray: see `classify_triangle`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Item {
    pub geometry: u32,
    pub primitive: u32,
    pub vertices: [u32; 3],
    pub degenerate: bool,
}

/// Shared-edge and shared-vertex topology of the triangles of one transform class of a bottom
/// level (spec, "Watertightness": identical transforms within a single instance).
#[derive(Debug, Default)]
pub(crate) struct Topology {
    /// Directed edge (from, to) by vertex position → triangles (geometry, primitive) having it.
    pub edges: HashMap<(PositionKey, PositionKey), Vec<(u32, u32)>>,
    /// Vertex position → triangles (geometry, primitive, corner) having it.
    pub vertices: HashMap<PositionKey, Vec<(u32, u32, u8)>>,
}

/// A vertex position as bits (see [`position_key`]).
pub(crate) type PositionKey = [u32; 3];

/// A position key: bit patterns with −0 read as +0 (identical position values).
pub(crate) fn position_key(p: [f32; 3]) -> [u32; 3] {
    p.map(|x| if x == 0.0 { 0 } else { x.to_bits() })
}

/// A triangle geometry's world vertex (each coordinate with its error bound) and its
/// ray-independent error radius: what a triangle's pre-test and classification read of each of its
/// vertices, in one cache line (a vertex read costs one line, where separate arrays of coordinates
/// and radii cost two or three).
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
pub(crate) struct WorldVertex {
    coords: [BoundedF64; 3],
    radius: f64,
}

const _: () = assert!(
    std::mem::size_of::<WorldVertex>() == 64,
    "a world vertex is one cache line"
);

/// A scene ready for tracing. Build once, trace many rays (`Sync`: rays may be traced in parallel).
pub struct PreparedScene {
    pub(crate) scene: Scene,
    pub(crate) instances: Vec<PreparedInstance>,
    pub(crate) geometries: Vec<WorldGeometry>,
    pub(crate) items: PageBacked<Item>,
    /// The triangle geometries' world vertices with their radii (see
    /// [`WorldGeometry::first_vertex`]).
    vertices: PageBacked<WorldVertex>,
    /// The far test of each item, in `items` order.
    pub(crate) item_far: PageBacked<ItemFar>,
    /// The pad constants the items' far tests share.
    pub(crate) far_constants: Vec<FarConstants>,
    /// Per item, where the scene has AABBs, the far box of the box's sphere (a triangle's own far
    /// box): a ray that misses it gets no report from the intersection shader, however the box
    /// is enlarged. Empty where every item is a triangle.
    pub(crate) sphere_far: Vec<FarBox>,
    /// The four-wide tree over `items` (see [`super::bvh`]).
    pub(crate) tree: WideTree,
    /// `(instance, geometry)` of every AABB geometry with an active box, in instance order.
    pub(crate) procedural: Vec<(u32, u32)>,
    /// Every geometry is opaque for a ray without opacity flags (its instance forces it opaque,
    /// or does not force it non-opaque and the geometry is opaque).
    pub(crate) all_opaque: bool,
    /// Every instance's mask has a bit set: a ray whose cull mask has all eight culls none.
    pub(crate) every_mask_set: bool,
    /// `(bottom level, transform class)` → topology, built on first use.
    pub(crate) topology: HashMap<(u32, u32), OnceLock<Topology>>,
    /// The least and greatest coordinate of every triangle's world vertices, and the largest
    /// `grow` and `shrink` of their instances' bands: what [`PreparedScene::in_f32_range`] asks.
    pub(crate) triangle_extent: Option<TriangleExtent>,
}

/// See [`PreparedScene::triangle_extent`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct TriangleExtent {
    lo: [f64; 3],
    hi: [f64; 3],
    grow: f64,
    shrink: f64,
}

impl std::fmt::Debug for PreparedScene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "PreparedScene({} instances, {} primitives, {} nodes)",
            self.instances.len(),
            self.items.len(),
            self.tree.len()
        )
    }
}

/// The far box of the sphere an AABB's intersection shader reports: the intersection shader reports
/// the sphere alone, so a ray that misses the sphere's padded box gets no report from the pair
/// however the box is enlarged. Every bound is one over the sphere's points: `extent`, the largest
/// corner norm of the sphere's box, is at least |c| + r. The corners `c ± r` are rounded in f64,
/// within 2⁻⁵³·extent, far below `slack`.
fn sphere_far_box(transform: &Transform3x4, band: &InstanceBand, sphere: &Sphere) -> FarBox {
    let k = band.kappa;
    let sse = BAND_SAFETY_FACTOR * SPHERE_SHADER_ERROR;
    let (c, r) = (sphere.center.map(f64::from), f64::from(sphere.radius));
    let (lo, hi, extent) = world_bounds(transform, |corner, k| {
        if corner >> k & 1 == 1 {
            c[k] + r
        } else {
            c[k] - r
        }
    });
    let slack = 1e-9 * (extent * band.norm_a + band.norm_t);
    FarBox::new(
        lo,
        hi,
        2.0 * band.norm_a * sse * 2.0 * extent + slack,
        // Dobj ≤ 2‖A⁻¹‖·M (centre and radius seen from the origin).
        4.0 * k * (band.direction_rel * k + sse) * 1.01,
        2.0 * k * (band.origin_coef + sse) * 1.01,
        band.norm_t,
    )
}

/// The far box of an AABB itself, for the exact ray: [`super::box_crossing`] requires a crossing
/// of the exact object-space ray through the box, which then meets the box's world image, inside
/// the world bounds of its eight corners (computed in f64, within `slack` of the exact ones).
fn box_far_box(transform: &Transform3x4, band: &InstanceBand, bx: &Aabb) -> FarBox {
    let (lo, hi, extent) = world_bounds(transform, |corner, k| {
        f64::from(if corner >> k & 1 == 1 {
            bx.max[k]
        } else {
            bx.min[k]
        })
    });
    let slack = 1e-9 * (extent * band.norm_a + band.norm_t);
    FarBox::new(lo, hi, slack, 0.0, 0.0, band.norm_t)
}

/// The world bounds of the eight object-space corners `corner(i, axis)` (i in 0..8) under
/// `transform`, and the largest corner norm in object space.
fn world_bounds(
    transform: &Transform3x4,
    corner: impl Fn(usize, usize) -> f64,
) -> ([f64; 3], [f64; 3], f64) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let mut extent: f64 = 0.0;
    for i in 0..8 {
        let p = [0, 1, 2].map(|k| corner(i, k));
        extent = extent.max(norm3(p));
        let w = transform.apply_f64(p);
        for k in 0..3 {
            lo[k] = lo[k].min(w[k]);
            hi[k] = hi[k].max(w[k]);
        }
    }
    (lo, hi, extent)
}

fn effective(m: Option<&Transform3x4>) -> Transform3x4 {
    m.copied().unwrap_or(Transform3x4::IDENTITY)
}

impl PreparedScene {
    /// Prepares a scene; fails with the scene's undefined things (see `Scene::undefined`).
    pub fn new(scene: &Scene) -> Result<PreparedScene, Vec<Problem>> {
        let problems = scene.undefined(&[]);
        if !problems.is_empty() {
            return Err(problems);
        }
        let mut instances = Vec::new();
        let mut geometries = Vec::new();
        let mut items = Vec::new();
        let mut boxes = Vec::new();
        // Every triangle geometry's world vertices and static radii, one geometry after another.
        let mut vertices: Vec<[BoundedF64; 3]> = Vec::new();
        let mut radius: Vec<f64> = Vec::new();
        let mut topology = HashMap::new();
        // Transform classes per bottom level: identical effective geometry transforms.
        let mut classes: Vec<Vec<u32>> = Vec::new();
        for (b, bl) in scene.bottom_levels.iter().enumerate() {
            let mut seen: Vec<Transform3x4> = Vec::new();
            let mut ids = Vec::new();
            for g in &bl.geometries {
                let m = match &g.data {
                    GeometryData::Triangles(t) => effective(t.transform.as_ref()),
                    GeometryData::Aabbs(_) => Transform3x4::IDENTITY,
                };
                let id = seen.iter().position(|x| *x == m).unwrap_or_else(|| {
                    seen.push(m);
                    seen.len() - 1
                });
                ids.push(id as u32);
                topology
                    .entry((b as u32, id as u32))
                    .or_insert_with(OnceLock::new);
            }
            classes.push(ids);
        }
        for (i, inst) in scene.instances.iter().enumerate() {
            let band = InstanceBand::new(&inst.transform);
            instances.push(PreparedInstance {
                band,
                det_negative: super::arith::determinant_sign(&inst.transform.0)
                    == std::cmp::Ordering::Less,
                identity: inst.transform.is_identity(),
            });
            let Some(b) = inst.bottom_level else { continue };
            let bl = &scene.bottom_levels[b as usize];
            for (g, geometry) in bl.geometries.iter().enumerate() {
                let gi = geometries.len() as u32;
                match &geometry.data {
                    GeometryData::Triangles(t) => {
                        let gm = t.transform.as_ref();
                        let first_vertex = vertices.len();
                        for p in &t.positions {
                            if p.iter().any(|x| !x.is_finite()) {
                                // Only inactive triangles reach such vertices; never used.
                                vertices.push([BoundedF64::from_f64_nan(); 3]);
                                radius.push(f64::INFINITY);
                                continue;
                            }
                            let obj = v3::<BoundedF64>(*p);
                            let as_space = match gm {
                                Some(m) => affine(&m.0, &obj),
                                None => obj,
                            };
                            let w = affine(&inst.transform.0, &as_space);
                            vertices.push(w);
                            radius.push(vertex_static_radius(
                                &band,
                                gm,
                                p.map(|x| x as f64),
                                as_space.map(|x| x.value),
                            ));
                        }
                        for prim in 0..t.primitive_count() {
                            if t.is_inactive(prim) {
                                continue;
                            }
                            let ids = t.vertex_indices(prim);
                            let mut lo = [f64::INFINITY; 3];
                            let mut hi = [f64::NEG_INFINITY; 3];
                            let mut pad: f64 = 0.0;
                            for &v in &ids {
                                for k in 0..3 {
                                    let x = vertices[first_vertex + v][k];
                                    lo[k] = lo[k].min(x.value - x.error);
                                    hi[k] = hi[k].max(x.value + x.error);
                                }
                                pad = pad.max(radius[first_vertex + v]);
                            }
                            boxes.push(FarBox::new(
                                lo,
                                hi,
                                pad,
                                band.test_rel + band.direction_rel,
                                band.origin_coef,
                                band.norm_t,
                            ));
                            items.push(Item {
                                geometry: gi,
                                primitive: prim as u32,
                                vertices: ids.map(|v| v as u32),
                                degenerate: {
                                    let p = t.vertices(prim);
                                    p[0] == p[1] || p[1] == p[2] || p[2] == p[0]
                                },
                            });
                        }
                        geometries.push(WorldGeometry {
                            instance: i as u32,
                            geometry: g as u32,
                            bottom_level: b,
                            kind: PrimitiveKind::Triangle,
                            first_vertex,
                            vertex_count: t.positions.len(),
                            transform_class: classes[b as usize][g],
                        });
                    }
                    GeometryData::Aabbs(a) => {
                        for (prim, (bx, sphere)) in a.boxes.iter().zip(&a.spheres).enumerate() {
                            if bx.is_inactive() {
                                continue;
                            }
                            // The walk must reach every box a ray robustly crosses (its shader
                            // must run, see `box_crossing`) and every sphere a ray may hit: the far
                            // box holds both. Which pairs reach the sphere's classification is
                            // decided by the sphere's own far box (`PreparedScene::sphere_far`).
                            boxes.push(
                                sphere_far_box(&inst.transform, &band, sphere).union(&box_far_box(
                                    &inst.transform,
                                    &band,
                                    bx,
                                )),
                            );
                            items.push(Item {
                                geometry: gi,
                                primitive: prim as u32,
                                vertices: [0; 3],
                                degenerate: false,
                            });
                        }
                        geometries.push(WorldGeometry {
                            instance: i as u32,
                            geometry: g as u32,
                            bottom_level: b,
                            kind: PrimitiveKind::Aabb,
                            first_vertex: vertices.len(),
                            vertex_count: 0,
                            transform_class: u32::MAX,
                        });
                    }
                }
            }
        }
        let triangle: Vec<bool> = items
            .iter()
            .map(|it: &Item| geometries[it.geometry as usize].kind == PrimitiveKind::Triangle)
            .collect();
        let (items, item_boxes, nodes) = build_bvh(items, boxes, &triangle);
        // Each AABB item's sphere far box, by item (none where the scene has no AABB).
        let sphere_far: Vec<FarBox> = if triangle.iter().all(|&t| t) {
            Vec::new()
        } else {
            items
                .iter()
                .zip(&item_boxes)
                .map(|(it, own): (&Item, &FarBox)| {
                    let w = &geometries[it.geometry as usize];
                    let GeometryData::Aabbs(a) = &scene.bottom_levels[w.bottom_level as usize]
                        .geometries[w.geometry as usize]
                        .data
                    else {
                        return *own;
                    };
                    let inst = &scene.instances[w.instance as usize];
                    let band = &instances[w.instance as usize].band;
                    sphere_far_box(&inst.transform, band, &a.spheres[it.primitive as usize])
                })
                .collect()
        };
        let item_bounds: Vec<BoundBox> = item_boxes.iter().map(BoundBox::of).collect();
        let (item_far, far_constants) = compact_far_boxes(&item_boxes);
        let item_triangles: Vec<bool> = items
            .iter()
            .map(|it: &Item| geometries[it.geometry as usize].kind == PrimitiveKind::Triangle)
            .collect();
        let tree = WideTree::new(&nodes, &item_bounds, &item_triangles);
        let procedural = geometries
            .iter()
            .filter(|w| w.kind == PrimitiveKind::Aabb)
            .filter(|w| {
                let GeometryData::Aabbs(a) = &scene.bottom_levels[w.bottom_level as usize]
                    .geometries[w.geometry as usize]
                    .data
                else {
                    unreachable!("an AABB geometry")
                };
                !a.boxes.iter().all(|b| b.is_inactive())
            })
            .map(|w| (w.instance, w.geometry))
            .collect();
        let all_opaque = geometries.iter().all(|w| {
            let inst = &scene.instances[w.instance as usize];
            let geometry =
                &scene.bottom_levels[w.bottom_level as usize].geometries[w.geometry as usize];
            inst.flags.force_opaque || (!inst.flags.force_no_opaque && geometry.flags.opaque)
        });
        let every_mask_set = scene.instances.iter().all(|inst| inst.mask != 0);
        let mut triangle_extent: Option<TriangleExtent> = None;
        for w in geometries
            .iter()
            .filter(|w| w.kind == PrimitiveKind::Triangle)
        {
            let band = &instances[w.instance as usize].band;
            for v in &vertices[w.first_vertex..w.first_vertex + w.vertex_count] {
                let e = triangle_extent.get_or_insert(TriangleExtent {
                    lo: [f64::INFINITY; 3],
                    hi: [f64::NEG_INFINITY; 3],
                    grow: 1.0,
                    shrink: 1.0,
                });
                for ((lo, hi), x) in e.lo.iter_mut().zip(&mut e.hi).zip(v) {
                    *lo = lo.min(x.value);
                    *hi = hi.max(x.value);
                }
                e.grow = e.grow.max(band.grow);
                e.shrink = e.shrink.max(band.shrink);
            }
        }
        Ok(PreparedScene {
            triangle_extent,
            all_opaque,
            every_mask_set,
            scene: scene.clone(),
            instances,
            geometries,
            items: PageBacked::new(items),
            vertices: PageBacked::new(
                vertices
                    .into_iter()
                    .zip(radius)
                    .map(|(coords, radius)| WorldVertex { coords, radius })
                    .collect(),
            ),
            item_far: PageBacked::new(item_far),
            far_constants,
            sphere_far,
            tree,
            procedural,
            topology,
        })
    }

    /// Whether an f32 test of `ray` against every triangle of the scene stays clear of overflow
    /// ([`super::band::within_f32_range`] for every pair at once: the farthest corner of the
    /// vertices' extent bounds every vertex's distance from the origin, and the instances' largest
    /// `grow` and `shrink` bound each one's). A scene without triangles: true.
    pub(crate) fn in_f32_range(&self, ray: &RayF64) -> bool {
        let Some(e) = &self.triangle_extent else {
            return true;
        };
        let far = |c: usize| {
            (e.lo[c] - ray.origin[c])
                .abs()
                .max((e.hi[c] - ray.origin[c]).abs())
        };
        let hi2 = far(0) * far(0) + far(1) * far(1) + far(2) * far(2);
        let d = ray.direction;
        super::band::range_holds(
            hi2,
            d[0] * d[0] + d[1] * d[1] + d[2] * d[2],
            e.grow,
            e.shrink,
        )
    }

    /// World vertex `i` of a triangle geometry (its vertex order), with its error bounds.
    #[inline]
    pub(crate) fn world_vertex(&self, w: &WorldGeometry, i: usize) -> &[BoundedF64; 3] {
        debug_assert!(i < w.vertex_count, "a vertex of the geometry");
        &self.vertices[w.first_vertex + i].coords
    }

    /// The static radius of world vertex `i` of a triangle geometry.
    #[inline]
    pub(crate) fn static_radius(&self, w: &WorldGeometry, i: usize) -> f64 {
        debug_assert!(i < w.vertex_count, "a vertex of the geometry");
        self.vertices[w.first_vertex + i].radius
    }

    /// Where a triangle geometry's world vertex records start, as an address for the cache to be
    /// asked for (computed without a bounds check; never read through here).
    #[inline]
    pub(crate) fn vertex_address(&self, w: &WorldGeometry) -> *const WorldVertex {
        self.vertices.as_ptr().wrapping_add(w.first_vertex)
    }

    /// The scene this was prepared from.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Number of active primitives in the BVH.
    pub fn primitive_count(&self) -> usize {
        self.items.len()
    }

    /// The topology of a bottom level's transform class.
    pub(crate) fn topology(&self, bottom_level: u32, class: u32) -> &Topology {
        self.topology[&(bottom_level, class)].get_or_init(|| {
            let mut t = Topology::default();
            let bl = &self.scene.bottom_levels[bottom_level as usize];
            let prepared_class = |g: usize| -> Option<u32> {
                let first_instance = self
                    .geometries
                    .iter()
                    .find(|w| w.bottom_level == bottom_level && w.geometry == g as u32)?;
                Some(first_instance.transform_class)
            };
            for (g, geometry) in bl.geometries.iter().enumerate() {
                let GeometryData::Triangles(tri) = &geometry.data else {
                    continue;
                };
                if prepared_class(g) != Some(class) {
                    continue;
                }
                for p in 0..tri.primitive_count() {
                    if tri.is_inactive(p) {
                        continue;
                    }
                    let v = tri.vertices(p).map(position_key);
                    for k in 0..3 {
                        t.edges
                            .entry((v[k], v[(k + 1) % 3]))
                            .or_default()
                            .push((g as u32, p as u32));
                        t.vertices
                            .entry(v[k])
                            .or_default()
                            .push((g as u32, p as u32, k as u8));
                    }
                }
            }
            t
        })
    }
}

impl BoundedF64 {
    pub(crate) fn from_f64_nan() -> BoundedF64 {
        BoundedF64 {
            value: f64::NAN,
            error: f64::INFINITY,
        }
    }
}

/// Relative slack on the pad bound of [`BoundBox`], far above the rounding of it and of the pad
/// it bounds.
const BOUND_SLACK: f64 = 1.0 + 1e-10;

#[cfg(test)]
mod tests {
    use super::{f32_down, f32_up};

    /// The f32 just above a finite `y` (+0 and −0 alike step to the least positive subnormal).
    fn step_up(y: f32) -> f32 {
        if y == 0.0 {
            f32::from_bits(1)
        } else if y > 0.0 {
            f32::from_bits(y.to_bits() + 1)
        } else {
            f32::from_bits(y.to_bits() - 1)
        }
    }

    /// Values near every kind of boundary: zeros, subnormals, powers of two, values between two
    /// f32s, the ends of the f32 range and beyond, infinities; and a spread of random ones.
    fn samples() -> Vec<f64> {
        let mut v = vec![
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            f32::from_bits(1) as f64,
            f32::from_bits(1) as f64 * 0.5,
            -(f32::from_bits(1) as f64) * 0.5,
            f32::MIN_POSITIVE as f64,
            1.0,
            -1.0,
            1.0 + 2f64.powi(-30),
            -(1.0 + 2f64.powi(-30)),
            1.0 - 2f64.powi(-30),
            f32::MAX as f64,
            f32::MAX as f64 * (1.0 + 2f64.powi(-40)),
            -(f32::MAX as f64) * (1.0 + 2f64.powi(-40)),
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        let mut state = 0x5eed_u64;
        for _ in 0..20_000 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            // Random mantissa bits, exponent within the f32 range and a little past it, either sign.
            let bits = (state >> 12) | ((1023 - 160 + (state >> 56) % 300) << 52);
            let x = f64::from_bits(bits);
            v.push(if state & 1 == 0 { x } else { -x });
        }
        v
    }

    #[test]
    fn f32_down_is_the_greatest_f32_at_most_x_and_f32_up_the_least_at_least() {
        for x in samples() {
            let d = f32_down(x);
            assert!(d as f64 <= x, "{x:e}: {d:e} is above");
            if d.is_finite() {
                assert!(step_up(d) as f64 > x, "{x:e}: {d:e} is not the greatest");
            } else {
                // −inf only where x is below every finite f32, +inf only for +inf.
                assert!(
                    (d == f32::NEG_INFINITY && x < f32::MIN as f64) || x == f64::INFINITY,
                    "{x:e}: {d:e}"
                );
            }
            let u = f32_up(x);
            assert!(u as f64 >= x, "{x:e}: {u:e} is below");
            if u.is_finite() {
                assert!((-step_up(-u) as f64) < x, "{x:e}: {u:e} is not the least");
            } else {
                assert!(
                    (u == f32::INFINITY && x > f32::MAX as f64) || x == f64::NEG_INFINITY,
                    "{x:e}: {u:e}"
                );
            }
        }
        // A zero keeps its sign, and NaN stays NaN.
        assert_eq!(f32_down(0.0).to_bits(), 0.0f32.to_bits());
        assert_eq!(f32_down(-0.0).to_bits(), (-0.0f32).to_bits());
        assert!(f32_down(f64::NAN).is_nan() && f32_up(f64::NAN).is_nan());
    }
}
