//! Geometric scenes for the reference tracer: bottom levels of triangles or of boxes that each carry
//! the sphere their intersection shader reports, instances with transforms and flags, and rays.
//!
//! Everything here is data (serde, readable YAML with `deny_unknown_fields`); what the spec leaves
//! undefined is found by [`Scene::undefined`], what a ray may hit is computed by `crate::tracer`.

pub mod build;
pub(crate) mod undefined;

pub use undefined::{Problem, ProblemKind};

use serde::{Deserialize, Serialize};

fn is_default<T: Default + PartialEq>(v: &T) -> bool {
    *v == T::default()
}

/// A row-major 3x4 affine matrix, `VkTransformMatrixKHR`: `p' = M[..3] · p + M[3]` per row.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Transform3x4(pub [[f32; 4]; 3]);

impl Default for Transform3x4 {
    fn default() -> Self {
        Transform3x4::IDENTITY
    }
}

impl Transform3x4 {
    pub const IDENTITY: Transform3x4 = Transform3x4([
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ]);

    /// A pure translation.
    pub fn translation(t: [f32; 3]) -> Transform3x4 {
        let mut m = Transform3x4::IDENTITY;
        for (r, row) in m.0.iter_mut().enumerate() {
            row[3] = t[r];
        }
        m
    }

    /// The 3x3 linear part, as f64 (exact).
    pub fn linear_f64(&self) -> [[f64; 3]; 3] {
        let m = &self.0;
        [0, 1, 2].map(|r| [0, 1, 2].map(|c| m[r][c] as f64))
    }

    /// The translation column, as f64 (exact).
    pub fn translation_f64(&self) -> [f64; 3] {
        [0, 1, 2].map(|r| self.0[r][3] as f64)
    }

    /// `self ∘ other` evaluated in f64 (rounded): for builders and bounds, never for decisions.
    pub fn apply_f64(&self, p: [f64; 3]) -> [f64; 3] {
        let m = &self.0;
        [0, 1, 2].map(|r| {
            m[r][0] as f64 * p[0] + m[r][1] as f64 * p[1] + m[r][2] as f64 * p[2] + m[r][3] as f64
        })
    }

    /// Whether every entry is finite.
    pub fn is_finite(&self) -> bool {
        self.0.iter().flatten().all(|x| x.is_finite())
    }

    /// Whether this is exactly the identity.
    pub fn is_identity(&self) -> bool {
        *self == Transform3x4::IDENTITY
    }
}

/// Everything a launch traces against: the bottom-level structures and the top level's instances.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    #[serde(default)]
    pub bottom_levels: Vec<BottomLevel>,
    #[serde(default)]
    pub instances: Vec<SceneInstance>,
}

/// One bottom-level acceleration structure; the geometry index is the position in `geometries`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BottomLevel {
    #[serde(default)]
    pub geometries: Vec<Geometry>,
}

/// `VkGeometryFlagsKHR`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeometryFlags {
    #[serde(default, skip_serializing_if = "is_default")]
    pub opaque: bool,
    #[serde(default, skip_serializing_if = "is_default")]
    pub no_duplicate_any_hit: bool,
}

/// One geometry of a bottom level.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Geometry {
    #[serde(default, skip_serializing_if = "is_default")]
    pub flags: GeometryFlags,
    pub data: GeometryData,
}

/// The primitives of a geometry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GeometryData {
    Triangles(Triangles),
    Aabbs(Aabbs),
}

/// Index data of an indexed triangle geometry (`VK_INDEX_TYPE_UINT16` / `UINT32`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Indices {
    #[serde(with = "crate::bulk")]
    U16(Vec<u16>),
    #[serde(with = "crate::bulk")]
    U32(Vec<u32>),
}

impl Indices {
    pub fn len(&self) -> usize {
        match self {
            Indices::U16(v) => v.len(),
            Indices::U32(v) => v.len(),
        }
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    pub fn get(&self, i: usize) -> u32 {
        match self {
            Indices::U16(v) => v[i] as u32,
            Indices::U32(v) => v[i],
        }
    }
}

/// A triangle geometry: three vertices per primitive, through `indices` when present.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Triangles {
    #[serde(with = "crate::bulk")]
    pub positions: Vec<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub indices: Option<Indices>,
    /// The geometry transform (`transformData`), applied when the bottom level is built.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transform: Option<Transform3x4>,
}

impl Triangles {
    /// Number of primitives (PrimitiveId runs over `0..count`, inactive ones included).
    pub fn primitive_count(&self) -> usize {
        match &self.indices {
            Some(ix) => ix.len() / 3,
            None => self.positions.len() / 3,
        }
    }

    /// The vertex indices of primitive `p` (callers check ranges with `Scene::undefined` first).
    pub fn vertex_indices(&self, p: usize) -> [usize; 3] {
        match &self.indices {
            Some(ix) => [0, 1, 2].map(|k| ix.get(3 * p + k) as usize),
            None => [3 * p, 3 * p + 1, 3 * p + 2],
        }
    }

    /// The three object-space (pre-transform) vertices of primitive `p`.
    pub fn vertices(&self, p: usize) -> [[f32; 3]; 3] {
        self.vertex_indices(p).map(|i| self.positions[i])
    }

    /// A triangle is inactive when the X component of any of its vertices is NaN (spec,
    /// "Inactive Primitives and Instances"): never hit, but it keeps its PrimitiveId.
    pub fn is_inactive(&self, p: usize) -> bool {
        self.vertices(p).iter().any(|v| v[0].is_nan())
    }
}

/// An axis-aligned box in the bottom level's space (`VkAabbPositionsKHR`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Aabb {
    pub min: [f32; 3],
    pub max: [f32; 3],
}

impl Aabb {
    /// An AABB is inactive when its minimum X is NaN (spec, "Inactive Primitives and Instances").
    pub fn is_inactive(&self) -> bool {
        self.min[0].is_nan()
    }
}

/// The sphere the intersection shader of a box reports (see `crate::tracer::aabb` for the shader).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sphere {
    pub center: [f32; 3],
    pub radius: f32,
}

/// A procedural geometry: boxes, and one sphere inside each box.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Aabbs {
    #[serde(with = "crate::bulk")]
    pub boxes: Vec<Aabb>,
    #[serde(with = "crate::bulk")]
    pub spheres: Vec<Sphere>,
}

/// `VkGeometryInstanceFlagsKHR`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InstanceFlags {
    #[serde(default, skip_serializing_if = "is_default")]
    pub triangle_facing_cull_disable: bool,
    #[serde(default, skip_serializing_if = "is_default")]
    pub flip_facing: bool,
    #[serde(default, skip_serializing_if = "is_default")]
    pub force_opaque: bool,
    #[serde(default, skip_serializing_if = "is_default")]
    pub force_no_opaque: bool,
}

fn full_mask() -> u8 {
    0xFF
}

/// One `VkAccelerationStructureInstanceKHR`; its InstanceId is its position in `Scene::instances`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneInstance {
    /// The bottom level it references; `None` is `accelerationStructureReference == 0` (inactive).
    pub bottom_level: Option<u32>,
    #[serde(default)]
    pub transform: Transform3x4,
    /// `instanceCustomIndex` (24 bits).
    #[serde(default, skip_serializing_if = "is_default")]
    pub custom_index: u32,
    #[serde(default = "full_mask")]
    pub mask: u8,
    /// `instanceShaderBindingTableRecordOffset` (24 bits).
    #[serde(default, skip_serializing_if = "is_default")]
    pub sbt_record_offset: u32,
    #[serde(default, skip_serializing_if = "is_default")]
    pub flags: InstanceFlags,
}

impl SceneInstance {
    /// An active instance of `bottom_level` with the identity transform and a full mask.
    pub fn of(bottom_level: u32) -> SceneInstance {
        SceneInstance {
            bottom_level: Some(bottom_level),
            transform: Transform3x4::IDENTITY,
            custom_index: 0,
            mask: 0xFF,
            sbt_record_offset: 0,
            flags: InstanceFlags::default(),
        }
    }
}

/// SPIR-V `Ray Flags` of a `traceRayEXT` call.
#[derive(Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct RayFlags(pub u32);

#[allow(non_upper_case_globals)]
impl RayFlags {
    pub const OPAQUE: RayFlags = RayFlags(1);
    pub const NO_OPAQUE: RayFlags = RayFlags(2);
    pub const TERMINATE_ON_FIRST_HIT: RayFlags = RayFlags(4);
    pub const SKIP_CLOSEST_HIT_SHADER: RayFlags = RayFlags(8);
    pub const CULL_BACK_FACING_TRIANGLES: RayFlags = RayFlags(16);
    pub const CULL_FRONT_FACING_TRIANGLES: RayFlags = RayFlags(32);
    pub const CULL_OPAQUE: RayFlags = RayFlags(64);
    pub const CULL_NO_OPAQUE: RayFlags = RayFlags(128);
    pub const SKIP_TRIANGLES: RayFlags = RayFlags(256);
    pub const SKIP_AABBS: RayFlags = RayFlags(512);
    /// Every flag with its SPIR-V name (without the `KHR` suffix).
    pub const NAMES: &'static [(&'static str, u32)] = &[
        ("OPAQUE", 1),
        ("NO_OPAQUE", 2),
        ("TERMINATE_ON_FIRST_HIT", 4),
        ("SKIP_CLOSEST_HIT_SHADER", 8),
        ("CULL_BACK_FACING_TRIANGLES", 16),
        ("CULL_FRONT_FACING_TRIANGLES", 32),
        ("CULL_OPAQUE", 64),
        ("CULL_NO_OPAQUE", 128),
        ("SKIP_TRIANGLES", 256),
        ("SKIP_AABBS", 512),
    ];
    /// The bits this model knows.
    pub const KNOWN: u32 = 0x3FF;

    pub const fn empty() -> RayFlags {
        RayFlags(0)
    }
    pub const fn contains(self, f: RayFlags) -> bool {
        self.0 & f.0 == f.0
    }
    pub const fn union(self, f: RayFlags) -> RayFlags {
        RayFlags(self.0 | f.0)
    }
    pub fn names(self) -> Vec<String> {
        let mut out: Vec<String> = Self::NAMES
            .iter()
            .filter(|(_, b)| self.0 & b != 0)
            .map(|(n, _)| n.to_string())
            .collect();
        if self.0 & !Self::KNOWN != 0 {
            out.push(format!("0x{:x}", self.0 & !Self::KNOWN));
        }
        out
    }
}

impl std::ops::BitOr for RayFlags {
    type Output = RayFlags;
    fn bitor(self, o: RayFlags) -> RayFlags {
        RayFlags(self.0 | o.0)
    }
}

impl std::fmt::Debug for RayFlags {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RayFlags({})", self.names().join(" | "))
    }
}

impl Serialize for RayFlags {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.names())
    }
}

impl<'de> Deserialize<'de> for RayFlags {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Form {
            Bits(u32),
            Names(Vec<String>),
        }
        match Form::deserialize(d)? {
            Form::Bits(b) => Ok(RayFlags(b)),
            Form::Names(names) => {
                let mut bits = 0u32;
                for n in &names {
                    let short = n.strip_suffix("_KHR").unwrap_or(n);
                    if let Some(hex) = short.strip_prefix("0x") {
                        bits |= u32::from_str_radix(hex, 16).map_err(|_| {
                            serde::de::Error::custom(format!("bad hex ray flag `{n}`"))
                        })?;
                    } else if let Some((_, b)) = RayFlags::NAMES.iter().find(|(x, _)| *x == short) {
                        bits |= b;
                    } else {
                        let known: Vec<&str> = RayFlags::NAMES.iter().map(|(n, _)| *n).collect();
                        return Err(serde::de::Error::custom(format!(
                            "unknown ray flag `{n}` (known: {})",
                            known.join(", ")
                        )));
                    }
                }
                Ok(RayFlags(bits))
            }
        }
    }
}

fn full_mask_u32() -> u32 {
    0xFF
}

/// The parameters of one `traceRayEXT` call; the hit point is `origin + t·direction` (not normalised).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ray {
    pub origin: [f32; 3],
    pub direction: [f32; 3],
    #[serde(default)]
    pub tmin: f32,
    /// `+inf` is allowed (`.inf` in YAML).
    pub tmax: f32,
    #[serde(default, skip_serializing_if = "is_default")]
    pub flags: RayFlags,
    #[serde(default = "full_mask_u32")]
    pub cull_mask: u32,
    #[serde(default, skip_serializing_if = "is_default")]
    pub sbt_offset: u32,
    #[serde(default, skip_serializing_if = "is_default")]
    pub sbt_stride: u32,
    #[serde(default, skip_serializing_if = "is_default")]
    pub miss_index: u32,
}

impl Ray {
    /// A ray with default flags, full cull mask and zero SBT parameters.
    pub fn new(origin: [f32; 3], direction: [f32; 3], tmin: f32, tmax: f32) -> Ray {
        Ray {
            origin,
            direction,
            tmin,
            tmax,
            flags: RayFlags::empty(),
            cull_mask: 0xFF,
            sbt_offset: 0,
            sbt_stride: 0,
            miss_index: 0,
        }
    }

    pub fn with_flags(mut self, flags: RayFlags) -> Ray {
        self.flags = flags;
        self
    }
}
