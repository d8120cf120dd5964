//! The rules of `vkCmdBuildAccelerationStructuresIndirectKHR`: every VUID the registry defines for the
//! command compiles to a predicate of the one rule table ([`crate::rules`]) — the implicit and common
//! shapes through the shared template compiler, the rest to an [`AccelPredicate`] by tag — or carries
//! a written reason. Rules about device-side contents (range records, instance records, pointer
//! arrays) are evaluated on the memory image of the world.

mod check;
mod update;

use super::call::{BuildGeometryInfo, BuildIndirect, BuildMode, GeometryData, IndexType};
use super::semantics::{indirect_ranges, instance_address, read_instance};
use super::world::{
    offset, AsType, BuildBuffer, BuildWorld, InstanceRecord, InstanceReference, Memory, RangeInfo,
};
use crate::call::Address;
use crate::profile::DeviceProfile;
use crate::rules::predicate::{Failure, Predicate};
use crate::rules::Source;
use crate::world::MemoryBinding;
use vk_registry::vuid::VuidRecord;

/// An address-valued field of a build info or its geometries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Field {
    Scratch,
    Vertex,
    Index,
    Transform,
    Aabbs,
    Instances,
    MotionVertex,
    MicromapIndex,
    /// Spheres (false) or linear swept spheres (true).
    SphereIndex(bool),
    SphereVertex(bool),
    SphereRadius(bool),
}

/// Which two kinds of memory must not overlap.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Overlap {
    /// 03701: dst of i against src of another update-mode info.
    DstSrcUpdateOther,
    /// 03702: dst of i against dst of another info.
    DstDstOther,
    /// 03703: dst of i against the scratch of any info.
    DstScratchAny,
    /// 03704: scratch of i against scratch of another info.
    ScratchScratchOther,
    /// 03705: scratch of i against src of any update-mode info.
    ScratchSrcUpdateAny,
    /// 03706: dst of i against any structure instances of another info reference.
    DstInstancedOther,
    /// 03668: src and dst of an update-mode info are the same structure or do not alias.
    SrcDstUpdateSame,
}

/// What an update-mode build must keep from the last build of its source.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Keep {
    InactiveStayInactive,
    ActiveStayActive,
    AllowUpdateBuilt,
    /// 03760: the info's `type`.
    StructureType,
    GeometryCount,
    Flags,
    GeometryType,
    GeometryFlags,
    VertexFormat,
    MaxVertex,
    IndexType,
    TransformNull,
    TransformNotNull,
    IndexValues,
    PrimitiveCount,
    FirstVertex,
    /// Dense geometry member: 0 numTriangles, 1 numVertices, 2 maxPrimitiveIndex, 3 maxGeometryIndex,
    /// 4 format, 5 dataSize.
    Dense(u8),
}

/// A build rule of the command's own (the command-buffer state and feature rules it shares with the
/// trace commands are [`Predicate`]s of their own).
#[derive(Debug, Clone, PartialEq)]
pub enum AccelPredicate {
    IndirectAddressMultipleOf(u64),
    IndirectStrideMultipleOf(u64),
    InfoCountPositive,
    ModeValid,
    DstValid,
    SrcValidIfNotNull,
    SrcNotNullIfUpdate,
    DistinctDst,
    SrcNotOtherDst,
    DstNotInstancedByOther,
    NoOverlap(Overlap),
    Keep(Keep),
    InputUsage,
    IndirectContiguous,
    IndirectRangeInOneBuffer,
    IndirectUsage,
    RangeRecordsValid,
    DstSizeEnough,
    /// The scratch range of the mode's size lies in one buffer; `skip_zero`: the rule only applies when
    /// the size is not zero.
    ScratchInOneBuffer {
        mode: BuildMode,
        skip_zero: bool,
    },
    /// The scratch buffer has STORAGE_BUFFER usage (for one mode with a non-zero size, or always).
    ScratchUsage(Option<BuildMode>),
    DstTypeMatches(AsType),
    DstBound,
    SrcBoundIfUpdate,
    InstancedBound,
    ScratchAligned,
    AlignedTo(Field, u64),
    VertexComponentAligned,
    IndexAligned,
    PointerElementsAligned(u64),
    MaxInstanceCount,
    ValidAddress(Field),
    ZeroAddress(Field),
    Contiguous(Field),
    InstanceReferenceValid,
    InstanceReferenceBottomLevel,
    OpacityMicromapsDisableAllowed,
    MaxCountsCoverRanges,
}

/// Reason for the implicit pointer/handle rules.
pub const POINTER_REASON: &str = "the case format passes every array the command takes as a value (infoCount elements \
     of pInfos, addresses, strides and maxima, each inner maxima array of geometryCount) and a live command buffer; a \
     dangling pointer or handle cannot be expressed, and passing one is undefined behaviour the layer's \
     parameter validation reports before any rule";

/// The hand-written rule of a tag.
fn by_tag(tag: &str) -> Option<AccelPredicate> {
    use AccelPredicate as P;
    use Field as F;
    Some(match tag {
        "03407" => P::DstNotInstancedByOther,
        "03698" => P::DistinctDst,
        "03701" => P::NoOverlap(Overlap::DstSrcUpdateOther),
        "03702" => P::NoOverlap(Overlap::DstDstOther),
        "03703" => P::NoOverlap(Overlap::DstScratchAny),
        "03704" => P::NoOverlap(Overlap::ScratchScratchOther),
        "03705" => P::NoOverlap(Overlap::ScratchSrcUpdateAny),
        "03706" => P::NoOverlap(Overlap::DstInstancedOther),
        "03668" => P::NoOverlap(Overlap::SrcDstUpdateSame),
        "03800" => P::DstValid,
        "04629" => P::SrcValidIfNotNull,
        "04630" => P::SrcNotNullIfUpdate,
        "03403" => P::SrcNotOtherDst,
        "03663" => P::Keep(Keep::InactiveStayInactive),
        "03664" => P::Keep(Keep::ActiveStayActive),
        "03667" => P::Keep(Keep::AllowUpdateBuilt),
        "03758" => P::Keep(Keep::GeometryCount),
        "03760" => P::Keep(Keep::StructureType),
        "03759" => P::Keep(Keep::Flags),
        "03761" => P::Keep(Keep::GeometryType),
        "03762" => P::Keep(Keep::GeometryFlags),
        "03763" => P::Keep(Keep::VertexFormat),
        "03764" => P::Keep(Keep::MaxVertex),
        "03765" => P::Keep(Keep::IndexType),
        "03766" => P::Keep(Keep::TransformNull),
        "03767" => P::Keep(Keep::TransformNotNull),
        "03768" => P::Keep(Keep::IndexValues),
        "03769" => P::Keep(Keep::PrimitiveCount),
        "03770" => P::Keep(Keep::FirstVertex),
        "10898" => P::Keep(Keep::Dense(0)),
        "10899" => P::Keep(Keep::Dense(1)),
        "10900" => P::Keep(Keep::Dense(2)),
        "10901" => P::Keep(Keep::Dense(3)),
        "10902" => P::Keep(Keep::Dense(4)),
        "10903" => P::Keep(Keep::Dense(5)),
        "03673" => P::InputUsage,
        "04628" => P::ModeValid,
        "03645" => P::IndirectContiguous,
        "03646" => P::IndirectRangeInOneBuffer,
        "03647" => P::IndirectUsage,
        "03651" => P::RangeRecordsValid,
        "03652" => P::DstSizeEnough,
        "03671" => P::ScratchInOneBuffer {
            mode: BuildMode::Build,
            skip_zero: false,
        },
        "03672" => P::ScratchInOneBuffer {
            mode: BuildMode::Update,
            skip_zero: false,
        },
        "12258" => P::ScratchInOneBuffer {
            mode: BuildMode::Build,
            skip_zero: true,
        },
        "12259" => P::ScratchInOneBuffer {
            mode: BuildMode::Update,
            skip_zero: true,
        },
        "03674" => P::ScratchUsage(None),
        "12260" => P::ScratchUsage(Some(BuildMode::Update)),
        "12261" => P::ScratchUsage(Some(BuildMode::Build)),
        "03699" => P::DstTypeMatches(AsType::TopLevel),
        "03700" => P::DstTypeMatches(AsType::BottomLevel),
        "03707" => P::DstBound,
        "03708" => P::SrcBoundIfUpdate,
        "03709" => P::InstancedBound,
        "03710" => P::ScratchAligned,
        "03711" => P::VertexComponentAligned,
        "03712" => P::IndexAligned,
        "03714" => P::AlignedTo(F::Aabbs, 8),
        "03715" => P::AlignedTo(F::Instances, 16),
        "03716" => P::AlignedTo(F::Instances, 8),
        "03717" => P::PointerElementsAligned(16),
        "03810" => P::AlignedTo(F::Transform, 16),
        "03801" => P::MaxInstanceCount,
        "03802" => P::ValidAddress(F::Scratch),
        "03803" => P::Contiguous(F::Scratch),
        "03804" => P::ValidAddress(F::Vertex),
        "03805" => P::Contiguous(F::Vertex),
        "03806" => P::ValidAddress(F::Index),
        "03807" => P::Contiguous(F::Index),
        "03808" => P::ValidAddress(F::Transform),
        "03809" => P::Contiguous(F::Transform),
        "03811" => P::ValidAddress(F::Aabbs),
        "03812" => P::Contiguous(F::Aabbs),
        "03813" => P::ValidAddress(F::Instances),
        "03814" => P::Contiguous(F::Instances),
        "11845" => P::ValidAddress(F::MotionVertex),
        "10904" => P::ZeroAddress(F::MicromapIndex),
        "10905" => P::ValidAddress(F::MicromapIndex),
        "11846" => P::ZeroAddress(F::SphereIndex(false)),
        "11847" => P::ValidAddress(F::SphereIndex(false)),
        "11848" => P::ValidAddress(F::SphereVertex(false)),
        "11849" => P::ValidAddress(F::SphereRadius(false)),
        "11850" => P::ZeroAddress(F::SphereIndex(true)),
        "11851" => P::ValidAddress(F::SphereIndex(true)),
        "11852" => P::ValidAddress(F::SphereVertex(true)),
        "11853" => P::ValidAddress(F::SphereRadius(true)),
        "06707" => P::InstanceReferenceValid,
        "12281" => P::InstanceReferenceBottomLevel,
        "10607" => P::OpacityMicromapsDisableAllowed,
        "03653" => P::MaxCountsCoverRanges,
        _ => return None,
    })
}

/// A compiled rule or why there is none.
#[derive(Debug, Clone, PartialEq)]
pub enum Compiled {
    Rule(Predicate, Source),
    NotExecutable(String),
    Pending(String),
}

/// Compiles one VUID record of the command: the pointer rules have a reason, the template compiler
/// reads the common shapes, the tag table the rest.
pub fn compile(r: &VuidRecord) -> Compiled {
    if r.tag == "parameter" {
        return Compiled::NotExecutable(POINTER_REASON.into());
    }
    if let Some(p) = crate::rules::template::compile(&r.scope, &r.scope, &r.text) {
        return Compiled::Rule(p, Source::Template);
    }
    if let Some(p) = by_tag(&r.tag) {
        return Compiled::Rule(Predicate::Accel(p), Source::Hand);
    }
    Compiled::Pending("no build rule is written for this tag yet".into())
}

/// What a build predicate sees: the device, the world with its memory image laid out once, the call.
pub(crate) struct AccelContext<'a> {
    profile: &'a DeviceProfile,
    world: &'a BuildWorld,
    call: &'a BuildIndirect,
    mem: Memory<'a>,
}

impl<'a> AccelContext<'a> {
    pub(crate) fn new(
        profile: &'a DeviceProfile,
        world: &'a BuildWorld,
        call: &'a BuildIndirect,
    ) -> AccelContext<'a> {
        AccelContext {
            profile,
            world,
            call,
            mem: world.memory(),
        }
    }

    /// Checks one build predicate against the call.
    pub(crate) fn check(&self, p: &AccelPredicate, out: &mut Vec<Failure>) {
        check::check(p, self, out)
    }
}

type Out = Vec<Failure>;

fn push(out: &mut Out, ctx: impl Into<String>, problem: impl Into<String>) {
    out.push(Failure {
        context: ctx.into(),
        problem: problem.into(),
    });
}

/// The addresses of a field in info `i`, with their context path, where the rule's condition holds.
fn field_addresses(info: &BuildGeometryInfo, i: usize, field: Field) -> Vec<(String, &Address)> {
    if field == Field::Scratch {
        return vec![(
            format!("pInfos[{i}].scratchData.deviceAddress"),
            &info.scratch,
        )];
    }
    let mut v = Vec::new();
    for (j, g) in info.geometries.iter().enumerate() {
        let base = format!("pInfos[{i}].pGeometries[{j}].geometry");
        match (&g.data, field) {
            (GeometryData::Triangles { vertex_data, .. }, Field::Vertex) => {
                v.push((format!("{base}.triangles.vertexData"), vertex_data))
            }
            (
                GeometryData::Triangles {
                    index_type,
                    index_data,
                    ..
                },
                Field::Index,
            ) if *index_type != IndexType::None => {
                v.push((format!("{base}.triangles.indexData"), index_data))
            }
            (GeometryData::Triangles { transform_data, .. }, Field::Transform) => {
                v.push((format!("{base}.triangles.transformData"), transform_data))
            }
            (
                GeometryData::Triangles {
                    motion_vertex_data: Some(a),
                    ..
                },
                Field::MotionVertex,
            ) => v.push((format!("{base}.triangles.pNext(motion).vertexData"), a)),
            (
                GeometryData::Triangles {
                    opacity_micromap: Some(m),
                    ..
                },
                Field::MicromapIndex,
            ) => v.push((
                format!("{base}.triangles.pNext(micromap).indexBuffer"),
                &m.index_buffer,
            )),
            (GeometryData::Aabbs { data, .. }, Field::Aabbs) => {
                v.push((format!("{base}.aabbs.data"), data))
            }
            (GeometryData::Instances { data, .. }, Field::Instances) => {
                v.push((format!("{base}.instances.data"), data))
            }
            (GeometryData::SpheresNv { index_data, .. }, Field::SphereIndex(false))
            | (GeometryData::LinearSweptSpheresNv { index_data, .. }, Field::SphereIndex(true)) => {
                v.push((format!("{base}.spheres.indexData"), index_data))
            }
            (GeometryData::SpheresNv { vertex_data, .. }, Field::SphereVertex(false))
            | (GeometryData::LinearSweptSpheresNv { vertex_data, .. }, Field::SphereVertex(true)) => {
                v.push((format!("{base}.spheres.vertexData"), vertex_data))
            }
            (GeometryData::SpheresNv { radius_data, .. }, Field::SphereRadius(false))
            | (GeometryData::LinearSweptSpheresNv { radius_data, .. }, Field::SphereRadius(true)) => {
                v.push((format!("{base}.spheres.radiusData"), radius_data))
            }
            _ => {}
        }
    }
    v
}

/// The index type that conditions a field's validity rule (micromap / sphere index fields).
fn field_index_type(info: &BuildGeometryInfo, j: usize, field: Field) -> Option<IndexType> {
    match (&info.geometries.get(j)?.data, field) {
        (
            GeometryData::Triangles {
                opacity_micromap: Some(m),
                ..
            },
            Field::MicromapIndex,
        ) => Some(m.index_type),
        (GeometryData::SpheresNv { index_type, .. }, Field::SphereIndex(false)) => {
            Some(*index_type)
        }
        (GeometryData::LinearSweptSpheresNv { index_type, .. }, Field::SphereIndex(true)) => {
            Some(*index_type)
        }
        _ => None,
    }
}

fn buffer_of<'w>(world: &'w BuildWorld, a: &Address) -> Option<&'w BuildBuffer> {
    world.buffer(a.buffer()?.0)
}

/// Why an address is not one `vkGetBufferDeviceAddress` gave (inside a buffer of the world), if it is not.
fn invalid_address(world: &BuildWorld, a: &Address) -> Option<String> {
    match a {
        Address::Raw(0) => Some("is 0".into()),
        Address::Raw(v) => Some(format!("{v:#x} lies in no buffer of the world")),
        Address::InBuffer { buffer, offset } => match world.buffer(buffer) {
            None => Some(format!("no buffer `{buffer}` in the world")),
            Some(b) if *offset >= b.size => Some(format!(
                "offset {offset} is past the end of `{buffer}` ({} bytes)",
                b.size
            )),
            Some(b) if b.memory == MemoryBinding::Unbound => Some(format!(
                "`{buffer}` is not bound to memory, so it has no address"
            )),
            _ => None,
        },
    }
}

fn not_contiguous(b: &BuildBuffer) -> bool {
    !b.is_sparse() && b.memory != MemoryBinding::Whole
}

/// A memory range `(buffer, offset, size)`.
type Span<'a> = (&'a str, u64, u64);

fn overlaps(a: Span, b: Span) -> bool {
    // A span that would pass u64::MAX ends there (no buffer reaches further).
    a.0 == b.0
        && a.2 > 0
        && b.2 > 0
        && a.1 < b.1.saturating_add(b.2)
        && b.1 < a.1.saturating_add(a.2)
}

fn scratch_size(cx: &AccelContext, i: usize) -> Option<u64> {
    let s = cx.world.sizes.get(i)?;
    match cx.call.infos[i].mode {
        BuildMode::Build => Some(s.build_scratch),
        BuildMode::Update => Some(s.update_scratch),
        BuildMode::Other(_) => None,
    }
}

fn scratch_span<'a>(cx: &'a AccelContext, i: usize) -> Option<Span<'a>> {
    let (b, off) = cx.call.infos[i].scratch.buffer()?;
    Some((b, off, scratch_size(cx, i)?))
}

fn structure_span<'a>(cx: &'a AccelContext, name: Option<&'a String>) -> Option<Span<'a>> {
    cx.world.backing(name?)
}

fn is_update(info: &BuildGeometryInfo) -> bool {
    info.mode == BuildMode::Update
}

/// The ranges of info `i` as the device reads them, when every record lies in memory.
fn ranges(cx: &AccelContext, i: usize) -> Option<Vec<RangeInfo>> {
    indirect_ranges(&cx.mem, cx.call, i).ok()
}

/// Every instance record info `i` reads through its ranges: (context, record address, record).
fn instances_of(cx: &AccelContext, i: usize) -> Vec<(String, InstanceRecord)> {
    let mut v = Vec::new();
    let Some(rs) = ranges(cx, i) else { return v };
    for (j, (g, r)) in cx.call.infos[i].geometries.iter().zip(&rs).enumerate() {
        if let GeometryData::Instances {
            array_of_pointers,
            data,
        } = &g.data
        {
            for k in 0..r.primitive_count.min(1 << 16) {
                let ctx = format!("pInfos[{i}].pGeometries[{j}] instance {k}");
                if let Ok(a) = instance_address(&cx.mem, data, *array_of_pointers, r, k, &ctx) {
                    if let Ok(rec) = read_instance(&cx.mem, &a, &ctx) {
                        v.push((ctx, rec));
                    }
                }
            }
        }
    }
    v
}

fn referenced_structures(cx: &AccelContext, i: usize) -> Vec<(String, String)> {
    instances_of(cx, i)
        .into_iter()
        .filter_map(|(c, r)| match r.reference {
            InstanceReference::Structure(n) => Some((c, n)),
            _ => None,
        })
        .collect()
}

/// Offsets `delta` bytes into a symbolic address (re-exported for generators).
pub fn at(a: &Address, delta: u64) -> Address {
    offset(a, delta)
}
