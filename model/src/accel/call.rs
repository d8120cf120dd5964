//! `vkCmdBuildAccelerationStructuresIndirectKHR` as a value: build geometry infos (type, flags, mode,
//! source and destination, geometries as an array or an array of pointers, scratch address), the
//! indirect addresses and strides of the range records, and `ppMaxPrimitiveCounts`.

use crate::call::Address;

/// `VkBuildAccelerationStructureFlagsKHR` as a bit mask.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(transparent)]
pub struct BuildFlags(pub u32);

impl BuildFlags {
    pub const ALLOW_UPDATE: u32 = 0x1;
    pub const ALLOW_COMPACTION: u32 = 0x2;
    pub const PREFER_FAST_TRACE: u32 = 0x4;
    pub const PREFER_FAST_BUILD: u32 = 0x8;
    pub const LOW_MEMORY: u32 = 0x10;
    pub const ALLOW_DISABLE_OPACITY_MICROMAPS_EXT: u32 = 0x80;
    pub fn has(self, bit: u32) -> bool {
        self.0 & bit == bit
    }
}

/// `VkGeometryFlagsKHR` (OPAQUE = 1, NO_DUPLICATE_ANY_HIT_INVOCATION = 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(transparent)]
pub struct GeometryFlags(pub u32);

/// `VkBuildAccelerationStructureModeKHR`, or a value outside the enumeration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BuildMode {
    Build,
    Update,
    /// Any other value (not a valid enumerant).
    Other(u32),
}

/// `VkIndexType` for triangle geometry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum IndexType {
    None,
    Uint8,
    Uint16,
    Uint32,
}

impl IndexType {
    /// Size in bytes of one index (0 for none).
    pub fn size(self) -> u64 {
        match self {
            IndexType::None => 0,
            IndexType::Uint8 => 1,
            IndexType::Uint16 => 2,
            IndexType::Uint32 => 4,
        }
    }
}

/// Vertex formats the model decodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum VertexFormat {
    R32g32b32Sfloat,
    R32g32Sfloat,
    R16g16b16a16Sfloat,
    R16g16Sfloat,
}

impl VertexFormat {
    /// Size of the smallest component.
    pub fn component_size(self) -> u64 {
        match self {
            VertexFormat::R32g32b32Sfloat | VertexFormat::R32g32Sfloat => 4,
            VertexFormat::R16g16b16a16Sfloat | VertexFormat::R16g16Sfloat => 2,
        }
    }
    /// Components that carry a position (z is 0 for two-component formats).
    pub fn components(self) -> usize {
        match self {
            VertexFormat::R32g32b32Sfloat | VertexFormat::R16g16b16a16Sfloat => 3,
            VertexFormat::R32g32Sfloat | VertexFormat::R16g16Sfloat => 2,
        }
    }
    /// The format has a fourth component (after the position's three), which the specification
    /// gives no meaning.
    pub fn has_fourth(self) -> bool {
        self == VertexFormat::R16g16b16a16Sfloat
    }
    /// Bytes of one whole vertex element.
    pub fn size(self) -> u64 {
        match self {
            VertexFormat::R32g32b32Sfloat => 12,
            VertexFormat::R32g32Sfloat => 8,
            VertexFormat::R16g16b16a16Sfloat => 8,
            VertexFormat::R16g16Sfloat => 4,
        }
    }
    pub fn vk_name(self) -> &'static str {
        match self {
            VertexFormat::R32g32b32Sfloat => "VK_FORMAT_R32G32B32_SFLOAT",
            VertexFormat::R32g32Sfloat => "VK_FORMAT_R32G32_SFLOAT",
            VertexFormat::R16g16b16a16Sfloat => "VK_FORMAT_R16G16B16A16_SFLOAT",
            VertexFormat::R16g16Sfloat => "VK_FORMAT_R16G16_SFLOAT",
        }
    }
}

/// `VkGeometryTypeKHR` of the geometries the model knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GeometryType {
    Triangles,
    Aabbs,
    Instances,
    SpheresNv,
    LinearSweptSpheresNv,
    DenseTrianglesAmdx,
}

/// `VkAccelerationStructureTrianglesOpacityMicromapEXT` in a triangles pNext chain (index part only).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpacityMicromap {
    pub index_type: IndexType,
    #[serde(default = "null")]
    pub index_buffer: Address,
}

/// The fields of `VkAccelerationStructureDenseGeometryFormatTrianglesDataAMDX` the update rules compare.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DenseTriangles {
    pub num_triangles: u32,
    pub num_vertices: u32,
    pub max_primitive_index: u32,
    pub max_geometry_index: u32,
    pub format: u32,
    pub data_size: u64,
}

/// The geometry data union of `VkAccelerationStructureGeometryKHR`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum GeometryData {
    Triangles {
        vertex_format: VertexFormat,
        vertex_data: Address,
        vertex_stride: u64,
        max_vertex: u32,
        index_type: IndexType,
        #[serde(default = "null")]
        index_data: Address,
        #[serde(default = "null")]
        transform_data: Address,
        /// `VkAccelerationStructureGeometryMotionTrianglesDataNV::vertexData`, when chained.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        motion_vertex_data: Option<Address>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        opacity_micromap: Option<OpacityMicromap>,
    },
    Aabbs {
        data: Address,
        stride: u64,
    },
    Instances {
        #[serde(default)]
        array_of_pointers: bool,
        data: Address,
    },
    /// `VK_GEOMETRY_TYPE_SPHERES_NV` (address fields only).
    SpheresNv {
        index_type: IndexType,
        #[serde(default = "null")]
        index_data: Address,
        vertex_data: Address,
        radius_data: Address,
    },
    /// `VK_GEOMETRY_TYPE_LINEAR_SWEPT_SPHERES_NV` (address fields only).
    LinearSweptSpheresNv {
        index_type: IndexType,
        #[serde(default = "null")]
        index_data: Address,
        vertex_data: Address,
        radius_data: Address,
    },
    /// `VK_GEOMETRY_TYPE_DENSE_GEOMETRY_FORMAT_TRIANGLES_AMDX` (the fields the update rules compare).
    DenseTrianglesAmdx(DenseTriangles),
}

fn null() -> Address {
    Address::NULL
}

impl GeometryData {
    pub fn geometry_type(&self) -> GeometryType {
        match self {
            GeometryData::Triangles { .. } => GeometryType::Triangles,
            GeometryData::Aabbs { .. } => GeometryType::Aabbs,
            GeometryData::Instances { .. } => GeometryType::Instances,
            GeometryData::SpheresNv { .. } => GeometryType::SpheresNv,
            GeometryData::LinearSweptSpheresNv { .. } => GeometryType::LinearSweptSpheresNv,
            GeometryData::DenseTrianglesAmdx(_) => GeometryType::DenseTrianglesAmdx,
        }
    }
}

/// One `VkAccelerationStructureGeometryKHR`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Geometry {
    #[serde(default)]
    pub flags: GeometryFlags,
    pub data: GeometryData,
}

/// One `VkAccelerationStructureBuildGeometryInfoKHR`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BuildGeometryInfo {
    #[serde(rename = "type")]
    pub ty: super::world::AsType,
    #[serde(default)]
    pub flags: BuildFlags,
    pub mode: BuildMode,
    /// `srcAccelerationStructure` by name; None is VK_NULL_HANDLE.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub src: Option<String>,
    /// `dstAccelerationStructure` by name; None is VK_NULL_HANDLE.
    pub dst: Option<String>,
    pub geometries: Vec<Geometry>,
    /// Passed through `ppGeometries` rather than `pGeometries` (same meaning).
    #[serde(default)]
    pub geometries_by_pointer: bool,
    pub scratch: Address,
}

/// `vkCmdBuildAccelerationStructuresIndirectKHR`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BuildIndirect {
    pub infos: Vec<BuildGeometryInfo>,
    pub indirect_addresses: Vec<Address>,
    pub indirect_strides: Vec<u32>,
    pub max_primitive_counts: Vec<Vec<u32>>,
}

impl BuildIndirect {
    /// The address of range record `j` of info `i`.
    pub fn range_address(&self, i: usize, j: usize) -> Option<Address> {
        let a = self.indirect_addresses.get(i)?;
        let s = *self.indirect_strides.get(i)? as u64;
        Some(super::world::offset(a, j as u64 * s))
    }
}
