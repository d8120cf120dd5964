//! The rules of `vkCmdBuildAccelerationStructuresIndirectKHR`: every VUID the registry defines for the
//! command compiles to a [`BuildPredicate`] (the implicit and common shapes from their text, the rest
//! by tag) or carries a written reason. Rules about device-side contents (range records, instance
//! records, pointer arrays) are evaluated on the memory image of the world.

use super::call::{
    BuildGeometryInfo, BuildIndirect, BuildMode, GeometryData, GeometryType, IndexType, COMMAND,
};
use super::semantics::{
    build_primitives, indirect_ranges, instance_address, range_indices, read_instance,
};
use super::world::{
    offset, AsType, BuildBuffer, BuildWorld, InstanceRecord, InstanceReference, Memory, RangeInfo,
};
use crate::call::Address;
use crate::flags::{BufferUsage, QueueFlags};
use crate::profile::DeviceProfile;
use crate::rules::Source;
use crate::verdict::{Verdict, Violation};
use crate::world::{CommandBufferLifecycle, MemoryBinding};
use regex::Regex;
use std::sync::OnceLock;
use vk_registry::vuid::{Condition, VuidRecord, VuidSet};

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

/// An executable build rule.
#[derive(Debug, Clone, PartialEq)]
pub enum BuildPredicate {
    FeatureEnabled(String),
    NotProtected,
    PoolSupports(QueueFlags),
    Recording,
    OutsideRenderPass,
    OutsideVideoCoding,
    NotBetweenSuspendedRenderPasses,
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

fn clean(s: &str) -> String {
    s.replace("pname:", "")
        .replace("sname:", "")
        .replace("ename:", "")
        .replace('`', "")
}

/// Text shapes shared with the trace commands' template compiler (implicit rules, features, multiples).
fn template(text: &str) -> Option<BuildPredicate> {
    static SHAPES: OnceLock<Vec<(Regex, fn(&regex::Captures) -> Option<BuildPredicate>)>> =
        OnceLock::new();
    let shapes = SHAPES.get_or_init(|| {
        let v: Vec<(&str, fn(&regex::Captures) -> Option<BuildPredicate>)> = vec![
            (r"^The (?:VkPhysicalDevice[A-Za-z]+::)?(?P<f>[A-Za-z0-9]+) feature must be enabled$", |m| {
                Some(BuildPredicate::FeatureEnabled(m["f"].to_string()))
            }),
            (r"^commandBuffer must not be a protected command buffer$", |_| Some(BuildPredicate::NotProtected)),
            (r"^commandBuffer must be in the recording state$", |_| Some(BuildPredicate::Recording)),
            (r"^The VkCommandPool that commandBuffer was allocated from must support (?:compute|VK_QUEUE_COMPUTE_BIT) operations$", |_| {
                Some(BuildPredicate::PoolSupports(QueueFlags::COMPUTE_BIT))
            }),
            (r"^This command must only be called outside of a render pass instance$", |_| Some(BuildPredicate::OutsideRenderPass)),
            (r"^This command must only be called outside of a video coding scope$", |_| Some(BuildPredicate::OutsideVideoCoding)),
            (r"^This command must not be called between suspended render pass instances$", |_| {
                Some(BuildPredicate::NotBetweenSuspendedRenderPasses)
            }),
            (r"^Each element of (?P<p>pIndirectDeviceAddresses|pIndirectStrides) must be a multiple of (?P<n>\d+)$", |m| {
                let n = m["n"].parse().ok()?;
                Some(if &m["p"] == "pIndirectStrides" {
                    BuildPredicate::IndirectStrideMultipleOf(n)
                } else {
                    BuildPredicate::IndirectAddressMultipleOf(n)
                })
            }),
            (r"^infoCount must be greater than 0$", |_| Some(BuildPredicate::InfoCountPositive)),
        ];
        v.into_iter().map(|(r, f)| (Regex::new(r).expect("valid regex"), f)).collect()
    });
    let t = clean(text);
    let t = t.trim().trim_end_matches('.');
    shapes
        .iter()
        .find_map(|(re, f)| re.captures(t).and_then(|m| f(&m)))
}

/// The hand-written rule of a tag.
fn by_tag(tag: &str) -> Option<BuildPredicate> {
    use BuildPredicate as P;
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
    Rule(BuildPredicate, Source),
    NotExecutable(String),
    Pending(String),
}

/// Compiles one VUID record of the command.
pub fn compile(r: &VuidRecord) -> Compiled {
    if r.tag == "parameter" {
        return Compiled::NotExecutable(POINTER_REASON.into());
    }
    if let Some(p) = template(&r.text) {
        return Compiled::Rule(p, Source::Template);
    }
    if let Some(p) = by_tag(&r.tag) {
        return Compiled::Rule(p, Source::Hand);
    }
    Compiled::Pending("no build rule is written for this tag yet".into())
}

/// One executable row of the build table.
#[derive(Debug, Clone)]
pub struct BuildRow {
    pub vuid: String,
    pub condition: Condition,
    pub predicate: BuildPredicate,
}

/// The executable build rules of one loaded registry version.
#[derive(Debug, Clone, Default)]
pub struct BuildRuleSet {
    pub rows: Vec<BuildRow>,
}

impl BuildRuleSet {
    pub fn from_vuids(set: &VuidSet) -> BuildRuleSet {
        let rows = set
            .records
            .iter()
            .filter(|r| r.scope == COMMAND)
            .filter_map(|r| match compile(r) {
                Compiled::Rule(p, _) => Some(BuildRow {
                    vuid: r.id.clone(),
                    condition: r.condition.clone(),
                    predicate: p,
                }),
                _ => None,
            })
            .collect();
        BuildRuleSet { rows }
    }

    /// The verdict on one call in one world on one device.
    pub fn validate(
        &self,
        profile: &DeviceProfile,
        world: &BuildWorld,
        call: &BuildIndirect,
    ) -> Verdict {
        let (major, minor) = profile.api_major_minor();
        let enabled = |name: &str| -> bool {
            if let Some(v) = name.strip_prefix("VK_VERSION_") {
                let mut it = v.split('_').map(|p| p.parse::<u32>().unwrap_or(0));
                return (major, minor) >= (it.next().unwrap_or(1), it.next().unwrap_or(0));
            }
            world.device.extension(name)
        };
        let mem = world.memory();
        let cx = Cx {
            profile,
            world,
            call,
            mem,
        };
        let mut violations = Vec::new();
        for row in self.rows.iter().filter(|r| r.condition.eval(&enabled)) {
            let mut out = Vec::new();
            check(&row.predicate, &cx, &mut out);
            for (context, problem) in out {
                violations.push(Violation {
                    vuid: row.vuid.clone(),
                    context,
                    problem,
                });
            }
        }
        violations.sort();
        violations.dedup();
        Verdict { violations }
    }
}

struct Cx<'a> {
    profile: &'a DeviceProfile,
    world: &'a BuildWorld,
    call: &'a BuildIndirect,
    mem: Memory<'a>,
}

type Out = Vec<(String, String)>;

fn push(out: &mut Out, ctx: impl Into<String>, problem: impl Into<String>) {
    out.push((ctx.into(), problem.into()));
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
    a.0 == b.0 && a.2 > 0 && b.2 > 0 && a.1 < b.1 + b.2 && b.1 < a.1 + a.2
}

fn scratch_size(cx: &Cx, i: usize) -> Option<u64> {
    let s = cx.world.sizes.get(i)?;
    match cx.call.infos[i].mode {
        BuildMode::Build => Some(s.build_scratch),
        BuildMode::Update => Some(s.update_scratch),
        BuildMode::Other(_) => None,
    }
}

fn scratch_span<'a>(cx: &'a Cx, i: usize) -> Option<Span<'a>> {
    let (b, off) = cx.call.infos[i].scratch.buffer()?;
    Some((b, off, scratch_size(cx, i)?))
}

fn structure_span<'a>(cx: &'a Cx, name: Option<&'a String>) -> Option<Span<'a>> {
    cx.world.backing(name?)
}

fn is_update(info: &BuildGeometryInfo) -> bool {
    info.mode == BuildMode::Update
}

/// The ranges of info `i` as the device reads them, when every record lies in memory.
fn ranges(cx: &Cx, i: usize) -> Option<Vec<RangeInfo>> {
    indirect_ranges(&cx.mem, cx.call, i).ok()
}

/// Every instance record info `i` reads through its ranges: (context, record address, record).
fn instances_of(cx: &Cx, i: usize) -> Vec<(String, InstanceRecord)> {
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

fn referenced_structures(cx: &Cx, i: usize) -> Vec<(String, String)> {
    instances_of(cx, i)
        .into_iter()
        .filter_map(|(c, r)| match r.reference {
            InstanceReference::Structure(n) => Some((c, n)),
            _ => None,
        })
        .collect()
}

fn check(p: &BuildPredicate, cx: &Cx, out: &mut Out) {
    use BuildPredicate as P;
    let w = cx.world;
    let call = cx.call;
    let cb = &w.command_buffer;
    match p {
        P::FeatureEnabled(f) => {
            if !w.device.feature(f) {
                push(
                    out,
                    "world.device.features",
                    format!("`{f}` is not enabled"),
                );
            }
        }
        P::NotProtected => {
            if cb.protected {
                push(out, "commandBuffer", "is a protected command buffer");
            }
        }
        P::PoolSupports(q) => {
            if !cb.pool_queue.intersects(*q) {
                push(
                    out,
                    "commandBuffer",
                    format!("its pool's queue family lacks {}", q.names().join(" or ")),
                );
            }
        }
        P::Recording => {
            if cb.lifecycle != CommandBufferLifecycle::Recording {
                push(
                    out,
                    "commandBuffer",
                    format!("is in the {:?} state", cb.lifecycle),
                );
            }
        }
        P::OutsideRenderPass => {
            if cb.in_render_pass {
                push(out, "commandBuffer", "is inside a render pass instance");
            }
        }
        P::OutsideVideoCoding => {
            if cb.in_video_coding {
                push(out, "commandBuffer", "is inside a video coding scope");
            }
        }
        P::NotBetweenSuspendedRenderPasses => {
            if w.between_suspended_render_passes {
                push(
                    out,
                    "commandBuffer",
                    "is between suspended render pass instances",
                );
            }
        }
        P::IndirectAddressMultipleOf(m) => {
            for (i, a) in call.indirect_addresses.iter().enumerate() {
                if a.alignment_value() % m != 0 {
                    push(
                        out,
                        format!("pIndirectDeviceAddresses[{i}]"),
                        format!("offset {} is not a multiple of {m}", a.alignment_value()),
                    );
                }
            }
        }
        P::IndirectStrideMultipleOf(m) => {
            for (i, s) in call.indirect_strides.iter().enumerate() {
                if *s as u64 % m != 0 {
                    push(
                        out,
                        format!("pIndirectStrides[{i}]"),
                        format!("{s} is not a multiple of {m}"),
                    );
                }
            }
        }
        P::InfoCountPositive => {
            if call.infos.is_empty() {
                push(out, "infoCount", "is 0");
            }
        }
        P::ModeValid => {
            for (i, info) in call.infos.iter().enumerate() {
                if let BuildMode::Other(v) = info.mode {
                    push(
                        out,
                        format!("pInfos[{i}].mode"),
                        format!("{v} is not a VkBuildAccelerationStructureModeKHR value"),
                    );
                }
            }
        }
        P::DstValid => {
            for (i, info) in call.infos.iter().enumerate() {
                match &info.dst {
                    None => push(
                        out,
                        format!("pInfos[{i}].dstAccelerationStructure"),
                        "is VK_NULL_HANDLE",
                    ),
                    Some(n) if w.structure(n).is_none() => push(
                        out,
                        format!("pInfos[{i}].dstAccelerationStructure"),
                        format!("`{n}` is not a structure of the world"),
                    ),
                    _ => {}
                }
            }
        }
        P::SrcValidIfNotNull => {
            for (i, info) in call.infos.iter().enumerate() {
                if let Some(n) = &info.src {
                    if w.structure(n).is_none() {
                        push(
                            out,
                            format!("pInfos[{i}].srcAccelerationStructure"),
                            format!("`{n}` is not a structure of the world"),
                        );
                    }
                }
            }
        }
        P::SrcNotNullIfUpdate => {
            for (i, info) in call.infos.iter().enumerate() {
                if is_update(info) && info.src.is_none() {
                    push(
                        out,
                        format!("pInfos[{i}].srcAccelerationStructure"),
                        "is VK_NULL_HANDLE in update mode",
                    );
                }
            }
        }
        P::DistinctDst => {
            for (i, a) in call.infos.iter().enumerate() {
                for (j, b) in call.infos.iter().enumerate().skip(i + 1) {
                    if a.dst.is_some() && a.dst == b.dst {
                        push(
                            out,
                            format!("pInfos[{j}].dstAccelerationStructure"),
                            format!("is also the destination of pInfos[{i}]"),
                        );
                    }
                }
            }
        }
        P::SrcNotOtherDst => {
            for (i, a) in call.infos.iter().enumerate() {
                for (j, b) in call.infos.iter().enumerate() {
                    if i != j && a.src.is_some() && a.src == b.dst {
                        push(
                            out,
                            format!("pInfos[{i}].srcAccelerationStructure"),
                            format!("is the destination of pInfos[{j}]"),
                        );
                    }
                }
            }
        }
        P::DstNotInstancedByOther => {
            for (i, a) in call.infos.iter().enumerate() {
                let Some(dst) = &a.dst else { continue };
                for j in (0..call.infos.len()).filter(|j| *j != i) {
                    for (ctx, n) in referenced_structures(cx, j) {
                        if &n == dst {
                            push(
                                out,
                                ctx,
                                format!("references `{dst}`, the destination of pInfos[{i}]"),
                            );
                        }
                    }
                }
            }
        }
        P::NoOverlap(kind) => check_overlap(*kind, cx, out),
        P::Keep(k) => check_keep(*k, cx, out),
        P::InputUsage => {
            for (i, info) in call.infos.iter().enumerate() {
                for f in [
                    Field::Vertex,
                    Field::Index,
                    Field::Transform,
                    Field::Aabbs,
                    Field::Instances,
                ] {
                    for (ctx, a) in field_addresses(info, i, f) {
                        if let Some(b) = buffer_of(w, a) {
                            if !b.usage.contains(
                                BufferUsage::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR,
                            ) {
                                push(out, ctx, format!("buffer `{}` lacks ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR", b.name));
                            }
                        }
                    }
                }
            }
        }
        P::IndirectContiguous => {
            for (i, a) in call.indirect_addresses.iter().enumerate() {
                if let Some(b) = buffer_of(w, a) {
                    if not_contiguous(b) {
                        push(
                            out,
                            format!("pIndirectDeviceAddresses[{i}]"),
                            format!("buffer `{}` is not bound to one memory object", b.name),
                        );
                    }
                }
            }
        }
        P::IndirectRangeInOneBuffer => {
            for (i, a) in call.indirect_addresses.iter().enumerate() {
                let n = call.infos.get(i).map_or(0, |g| g.geometries.len()) as u64;
                let len = n * *call.indirect_strides.get(i).unwrap_or(&0) as u64;
                if len == 0 {
                    continue;
                }
                let ctx = format!("pIndirectDeviceAddresses[{i}]");
                match a.buffer() {
                    Some((name, off)) => match w.buffer(name) {
                        Some(b) if off.saturating_add(len) <= b.size => {}
                        Some(b) => push(
                            out,
                            ctx,
                            format!(
                                "[{off}, {off}+{len}) passes the end of `{}` ({} bytes)",
                                b.name, b.size
                            ),
                        ),
                        None => push(out, ctx, format!("no buffer `{name}` in the world")),
                    },
                    None => push(out, ctx, "the address lies in no buffer of the world"),
                }
            }
        }
        P::IndirectUsage => {
            for (i, a) in call.indirect_addresses.iter().enumerate() {
                if let Some(b) = buffer_of(w, a) {
                    if !b.usage.contains(BufferUsage::INDIRECT_BUFFER_BIT) {
                        push(
                            out,
                            format!("pIndirectDeviceAddresses[{i}]"),
                            format!("buffer `{}` lacks INDIRECT_BUFFER_BIT", b.name),
                        );
                    }
                }
            }
        }
        P::RangeRecordsValid => check_range_records(cx, out),
        P::DstSizeEnough => {
            for (i, info) in call.infos.iter().enumerate() {
                let (Some(s), Some(need)) = (
                    info.dst.as_ref().and_then(|d| w.structure(d)),
                    w.sizes.get(i),
                ) else {
                    continue;
                };
                if s.size < need.structure {
                    push(
                        out,
                        format!("pInfos[{i}].dstAccelerationStructure"),
                        format!(
                            "`{}` has size {} < {} required",
                            s.name, s.size, need.structure
                        ),
                    );
                }
            }
        }
        P::ScratchInOneBuffer { mode, skip_zero } => {
            for (i, info) in call.infos.iter().enumerate() {
                if info.mode != *mode {
                    continue;
                }
                let Some(n) = scratch_size(cx, i) else {
                    continue;
                };
                if n == 0 && *skip_zero {
                    continue;
                }
                let ctx = format!("pInfos[{i}].scratchData.deviceAddress");
                match info
                    .scratch
                    .buffer()
                    .and_then(|(b, o)| Some((w.buffer(b)?, o)))
                {
                    Some((b, o)) if o.saturating_add(n) <= b.size => {}
                    Some((b, o)) => push(
                        out,
                        ctx,
                        format!(
                            "[{o}, {o}+{n}) passes the end of `{}` ({} bytes)",
                            b.name, b.size
                        ),
                    ),
                    None if n == 0 => {}
                    None => push(out, ctx, "lies in no buffer of the world"),
                }
            }
        }
        P::ScratchUsage(mode) => {
            for (i, info) in call.infos.iter().enumerate() {
                if let Some(m) = mode {
                    if info.mode != *m || scratch_size(cx, i).unwrap_or(1) == 0 {
                        continue;
                    }
                }
                if let Some(b) = buffer_of(w, &info.scratch) {
                    if !b.usage.contains(BufferUsage::STORAGE_BUFFER_BIT) {
                        push(
                            out,
                            format!("pInfos[{i}].scratchData.deviceAddress"),
                            format!("buffer `{}` lacks STORAGE_BUFFER_BIT", b.name),
                        );
                    }
                } else if mode.is_some() {
                    if let Some(why) = invalid_address(w, &info.scratch) {
                        push(out, format!("pInfos[{i}].scratchData.deviceAddress"), why);
                    }
                }
            }
        }
        P::DstTypeMatches(t) => {
            for (i, info) in call.infos.iter().enumerate() {
                if info.ty != *t {
                    continue;
                }
                if let Some(s) = info.dst.as_ref().and_then(|d| w.structure(d)) {
                    if s.ty != *t && s.ty != AsType::Generic {
                        push(
                            out,
                            format!("pInfos[{i}].dstAccelerationStructure"),
                            format!("`{}` was created as {:?}", s.name, s.ty),
                        );
                    }
                }
            }
        }
        P::DstBound | P::SrcBoundIfUpdate => {
            for (i, info) in call.infos.iter().enumerate() {
                let (name, what) = match p {
                    P::DstBound => (info.dst.as_ref(), "dstAccelerationStructure"),
                    _ if is_update(info) => (info.src.as_ref(), "srcAccelerationStructure"),
                    _ => continue,
                };
                if let Some(b) = name
                    .and_then(|n| w.structure(n))
                    .and_then(|s| w.buffer(&s.buffer))
                {
                    if b.memory == MemoryBinding::Unbound {
                        push(
                            out,
                            format!("pInfos[{i}].{what}"),
                            format!("its buffer `{}` is not bound to memory", b.name),
                        );
                    }
                }
            }
        }
        P::InstancedBound => {
            for i in 0..call.infos.len() {
                for (ctx, n) in referenced_structures(cx, i) {
                    if let Some(b) = w.structure(&n).and_then(|s| w.buffer(&s.buffer)) {
                        if b.memory == MemoryBinding::Unbound {
                            push(
                                out,
                                ctx,
                                format!(
                                    "references `{n}` whose buffer `{}` is not bound to memory",
                                    b.name
                                ),
                            );
                        }
                    }
                }
            }
        }
        P::ScratchAligned => {
            let Some(m) = cx.profile.limit("VkPhysicalDeviceAccelerationStructurePropertiesKHR::minAccelerationStructureScratchOffsetAlignment") else { return };
            for (i, info) in call.infos.iter().enumerate() {
                let v = info.scratch.alignment_value();
                if m > 0 && v % m != 0 {
                    push(out, format!("pInfos[{i}].scratchData.deviceAddress"), format!("offset {v} is not a multiple of minAccelerationStructureScratchOffsetAlignment ({m})"));
                }
            }
        }
        P::AlignedTo(field, m) => {
            for (i, info) in call.infos.iter().enumerate() {
                for (j, g) in info.geometries.iter().enumerate() {
                    let a = match (&g.data, field) {
                        (GeometryData::Aabbs { data, .. }, Field::Aabbs) => data,
                        (
                            GeometryData::Instances {
                                data,
                                array_of_pointers,
                            },
                            Field::Instances,
                        ) if (*m == 8) == *array_of_pointers => data,
                        (GeometryData::Triangles { transform_data, .. }, Field::Transform)
                            if !transform_data.is_null() =>
                        {
                            transform_data
                        }
                        _ => continue,
                    };
                    if a.alignment_value() % m != 0 {
                        push(
                            out,
                            format!("pInfos[{i}].pGeometries[{j}]"),
                            format!(
                                "address offset {} is not aligned to {m}",
                                a.alignment_value()
                            ),
                        );
                    }
                }
            }
        }
        P::VertexComponentAligned | P::IndexAligned => {
            for (i, info) in call.infos.iter().enumerate() {
                for (j, g) in info.geometries.iter().enumerate() {
                    if let GeometryData::Triangles {
                        vertex_format,
                        vertex_data,
                        index_type,
                        index_data,
                        ..
                    } = &g.data
                    {
                        let (a, m, what) = if matches!(p, P::VertexComponentAligned) {
                            (vertex_data, vertex_format.component_size(), "vertexData")
                        } else if *index_type != IndexType::None {
                            (index_data, index_type.size(), "indexData")
                        } else {
                            continue;
                        };
                        if a.alignment_value() % m != 0 {
                            push(
                                out,
                                format!("pInfos[{i}].pGeometries[{j}].geometry.triangles.{what}"),
                                format!("offset {} is not aligned to {m}", a.alignment_value()),
                            );
                        }
                    }
                }
            }
        }
        P::PointerElementsAligned(m) => {
            for (i, info) in call.infos.iter().enumerate() {
                let Some(rs) = ranges(cx, i) else { continue };
                for (j, (g, r)) in info.geometries.iter().zip(&rs).enumerate() {
                    if let GeometryData::Instances {
                        array_of_pointers: true,
                        data,
                    } = &g.data
                    {
                        for k in 0..r.primitive_count.min(1 << 16) {
                            let ctx = format!("pInfos[{i}].pGeometries[{j}] pointer {k}");
                            if let Ok(a) = instance_address(&cx.mem, data, true, r, k, &ctx) {
                                if a.alignment_value() % m != 0 {
                                    push(
                                        out,
                                        ctx,
                                        format!(
                                            "points at offset {} which is not aligned to {m}",
                                            a.alignment_value()
                                        ),
                                    );
                                }
                            }
                        }
                    }
                }
            }
        }
        P::MaxInstanceCount => {
            let Some(m) = cx
                .profile
                .limit("VkPhysicalDeviceAccelerationStructurePropertiesKHR::maxInstanceCount")
            else {
                return;
            };
            for (i, info) in call.infos.iter().enumerate() {
                for (j, g) in info.geometries.iter().enumerate() {
                    if g.data.geometry_type() == GeometryType::Instances {
                        let c = call
                            .max_primitive_counts
                            .get(i)
                            .and_then(|v| v.get(j))
                            .copied()
                            .unwrap_or(0) as u64;
                        if c > m {
                            push(
                                out,
                                format!("ppMaxPrimitiveCounts[{i}][{j}]"),
                                format!("{c} is greater than maxInstanceCount ({m})"),
                            );
                        }
                    }
                }
            }
        }
        P::ValidAddress(field) => {
            for (i, info) in call.infos.iter().enumerate() {
                for (n, (ctx, a)) in field_addresses(info, i, *field).into_iter().enumerate() {
                    // Conditions: transform only when not 0; micromap and sphere index only when indexed.
                    if *field == Field::Transform && a.is_null() {
                        continue;
                    }
                    if matches!(field, Field::MicromapIndex | Field::SphereIndex(_)) {
                        let j = geometry_of(info, i, *field, n);
                        if field_index_type(info, j, *field) == Some(IndexType::None) {
                            continue;
                        }
                    }
                    if let Some(why) = invalid_address(w, a) {
                        push(out, ctx, why);
                    }
                }
            }
        }
        P::ZeroAddress(field) => {
            for (i, info) in call.infos.iter().enumerate() {
                for (n, (ctx, a)) in field_addresses(info, i, *field).into_iter().enumerate() {
                    let j = geometry_of(info, i, *field, n);
                    if field_index_type(info, j, *field) == Some(IndexType::None) && !a.is_null() {
                        push(
                            out,
                            ctx,
                            "is not 0 although the index type is VK_INDEX_TYPE_NONE_KHR",
                        );
                    }
                }
            }
        }
        P::Contiguous(field) => {
            for (i, info) in call.infos.iter().enumerate() {
                for (ctx, a) in field_addresses(info, i, *field) {
                    if let Some(b) = buffer_of(w, a) {
                        if not_contiguous(b) {
                            push(
                                out,
                                ctx,
                                format!("buffer `{}` is not bound to one memory object", b.name),
                            );
                        }
                    }
                }
            }
        }
        P::InstanceReferenceValid | P::InstanceReferenceBottomLevel => {
            for i in 0..call.infos.len() {
                for (ctx, rec) in instances_of(cx, i) {
                    match &rec.reference {
                        InstanceReference::Null => {}
                        InstanceReference::Raw(v) => push(
                            out,
                            ctx,
                            format!(
                                "accelerationStructureReference {v:#x} is no structure's address"
                            ),
                        ),
                        InstanceReference::Structure(n) => match w.structure(n) {
                            None => push(
                                out,
                                ctx,
                                format!("references `{n}`, not a structure of the world"),
                            ),
                            Some(s)
                                if matches!(p, P::InstanceReferenceBottomLevel)
                                    && s.ty == AsType::TopLevel =>
                            {
                                push(out, ctx, format!("references `{n}`, a top-level structure"))
                            }
                            _ => {}
                        },
                    }
                }
            }
        }
        P::OpacityMicromapsDisableAllowed => {
            for i in 0..call.infos.len() {
                for (ctx, rec) in instances_of(cx, i) {
                    if rec.flags & super::world::INSTANCE_DISABLE_OPACITY_MICROMAPS == 0 {
                        continue;
                    }
                    if let InstanceReference::Structure(n) = &rec.reference {
                        let allowed = w
                            .structure(n)
                            .and_then(|s| s.last_build.as_ref())
                            .is_some_and(|b| {
                                b.flags.has(
                                    super::call::BuildFlags::ALLOW_DISABLE_OPACITY_MICROMAPS_EXT,
                                )
                            });
                        if !allowed {
                            push(out, ctx, format!("sets DISABLE_OPACITY_MICROMAPS but `{n}` was not built with ALLOW_DISABLE_OPACITY_MICROMAPS"));
                        }
                    }
                }
            }
        }
        P::MaxCountsCoverRanges => {
            for i in 0..call.infos.len() {
                let Some(rs) = ranges(cx, i) else { continue };
                for (j, r) in rs.iter().enumerate() {
                    let m = call
                        .max_primitive_counts
                        .get(i)
                        .and_then(|v| v.get(j))
                        .copied()
                        .unwrap_or(0);
                    if r.primitive_count > m {
                        push(
                            out,
                            format!("ppMaxPrimitiveCounts[{i}][{j}]"),
                            format!(
                                "{m} is less than the primitiveCount {} in memory",
                                r.primitive_count
                            ),
                        );
                    }
                }
            }
        }
    }
}

/// The geometry index of the n-th address `field_addresses` returned for a field.
fn geometry_of(info: &BuildGeometryInfo, i: usize, field: Field, n: usize) -> usize {
    let mut seen = 0;
    for j in 0..info.geometries.len() {
        let one = BuildGeometryInfo {
            geometries: vec![info.geometries[j].clone()],
            ..info.clone()
        };
        let k = field_addresses(&one, i, field).len();
        if n < seen + k {
            return j;
        }
        seen += k;
    }
    0
}

fn check_overlap(kind: Overlap, cx: &Cx, out: &mut Out) {
    let infos = &cx.call.infos;
    for (i, a) in infos.iter().enumerate() {
        for (j, b) in infos.iter().enumerate() {
            let other = i != j;
            let (x, y, what) = match kind {
                Overlap::DstSrcUpdateOther if other && is_update(b) => (
                    structure_span(cx, a.dst.as_ref()),
                    structure_span(cx, b.src.as_ref()),
                    "the source of update pInfos",
                ),
                Overlap::DstDstOther if other && i < j => (
                    structure_span(cx, a.dst.as_ref()),
                    structure_span(cx, b.dst.as_ref()),
                    "the destination of pInfos",
                ),
                Overlap::DstScratchAny => (
                    structure_span(cx, a.dst.as_ref()),
                    scratch_span(cx, j),
                    "the scratch of pInfos",
                ),
                Overlap::ScratchScratchOther if other && i < j => (
                    scratch_span(cx, i),
                    scratch_span(cx, j),
                    "the scratch of pInfos",
                ),
                Overlap::ScratchSrcUpdateAny if is_update(b) => (
                    scratch_span(cx, i),
                    structure_span(cx, b.src.as_ref()),
                    "the source of update pInfos",
                ),
                Overlap::SrcDstUpdateSame if i == j && is_update(a) && a.src != a.dst => (
                    structure_span(cx, a.src.as_ref()),
                    structure_span(cx, a.dst.as_ref()),
                    "its own destination, pInfos",
                ),
                Overlap::DstInstancedOther if other => {
                    let Some(x) = structure_span(cx, a.dst.as_ref()) else {
                        continue;
                    };
                    for (ctx, n) in referenced_structures(cx, j) {
                        if let Some(y) = cx.world.backing(&n) {
                            if overlaps(x, y) && a.dst.as_deref() != Some(n.as_str()) {
                                push(
                                    out,
                                    format!("pInfos[{i}].dstAccelerationStructure"),
                                    format!("overlaps `{n}`, referenced by {ctx}"),
                                );
                            }
                        }
                    }
                    continue;
                }
                _ => continue,
            };
            if let (Some(x), Some(y)) = (x, y) {
                if overlaps(x, y) {
                    let ctx = match kind {
                        Overlap::ScratchScratchOther | Overlap::ScratchSrcUpdateAny => {
                            format!("pInfos[{i}].scratchData")
                        }
                        Overlap::SrcDstUpdateSame => {
                            format!("pInfos[{i}].srcAccelerationStructure")
                        }
                        _ => format!("pInfos[{i}].dstAccelerationStructure"),
                    };
                    push(
                        out,
                        ctx,
                        format!(
                            "[{}+{}, +{}) overlaps {what}[{j}] [{}+{}, +{})",
                            x.0, x.1, x.2, y.0, y.1, y.2
                        ),
                    );
                }
            }
        }
    }
}

fn check_keep(k: Keep, cx: &Cx, out: &mut Out) {
    use super::call::BuildFlags;
    for (i, info) in cx.call.infos.iter().enumerate() {
        if !is_update(info) {
            continue;
        }
        let Some(src) = info.src.as_ref().and_then(|n| cx.world.structure(n)) else {
            continue;
        };
        let ctx = format!("pInfos[{i}]");
        let Some(last) = &src.last_build else {
            if k == Keep::AllowUpdateBuilt {
                push(out, ctx, format!("`{}` was never built", src.name));
            }
            continue;
        };
        match k {
            Keep::AllowUpdateBuilt => {
                if !last.flags.has(BuildFlags::ALLOW_UPDATE) {
                    push(
                        out,
                        ctx,
                        format!("`{}` was not built with ALLOW_UPDATE", src.name),
                    );
                }
                continue;
            }
            Keep::GeometryCount => {
                if last.geometries.len() != info.geometries.len() {
                    push(
                        out,
                        format!("{ctx}.geometryCount"),
                        format!(
                            "{} differs from the last build's {}",
                            info.geometries.len(),
                            last.geometries.len()
                        ),
                    );
                }
                continue;
            }
            Keep::StructureType => {
                if last.ty != info.ty {
                    push(
                        out,
                        format!("{ctx}.type"),
                        format!("{:?} differs from the last build's {:?}", info.ty, last.ty),
                    );
                }
                continue;
            }
            Keep::Flags => {
                if last.flags != info.flags {
                    push(
                        out,
                        format!("{ctx}.flags"),
                        format!(
                            "{:#x} differs from the last build's {:#x}",
                            info.flags.0, last.flags.0
                        ),
                    );
                }
                continue;
            }
            _ => {}
        }
        let rs = ranges(cx, i);
        let now_prims = rs
            .as_ref()
            .and_then(|r| build_primitives(&cx.mem, info, r).ok());
        for (j, (g, l)) in info.geometries.iter().zip(&last.geometries).enumerate() {
            let gctx = format!("{ctx}.pGeometries[{j}]");
            let range = rs.as_ref().and_then(|r| r.get(j));
            let tri = match &g.data {
                GeometryData::Triangles {
                    vertex_format,
                    max_vertex,
                    index_type,
                    transform_data,
                    ..
                } => Some((
                    *vertex_format,
                    *max_vertex,
                    *index_type,
                    !transform_data.is_null(),
                )),
                _ => None,
            };
            let bad: Option<String> = match k {
                Keep::GeometryType => (g.data.geometry_type() != l.geometry_type)
                    .then(|| "geometryType changed".into()),
                Keep::GeometryFlags => (g.flags != l.flags).then(|| "flags changed".into()),
                Keep::VertexFormat => tri
                    .filter(|t| Some(t.0) != l.vertex_format)
                    .map(|_| "vertexFormat changed".into()),
                Keep::MaxVertex => tri
                    .filter(|t| t.1 != l.max_vertex)
                    .map(|_| "maxVertex changed".into()),
                Keep::IndexType => tri
                    .filter(|t| Some(t.2) != l.index_type)
                    .map(|_| "indexType changed".into()),
                Keep::TransformNull => tri
                    .filter(|t| !l.has_transform && t.3)
                    .map(|_| "transformData was NULL and is not".into()),
                Keep::TransformNotNull => tri
                    .filter(|t| l.has_transform && !t.3)
                    .map(|_| "transformData was not NULL and is".into()),
                Keep::IndexValues => match (tri, range) {
                    (Some(t), Some(r)) if t.2 != IndexType::None => {
                        let now = range_indices(&cx.mem, &g.data, r, &gctx).unwrap_or_default();
                        (now != l.indices).then(|| "index values differ from the last build".into())
                    }
                    _ => None,
                },
                Keep::PrimitiveCount => range
                    .filter(|r| r.primitive_count != l.range.primitive_count)
                    .map(|r| {
                        format!(
                            "primitiveCount {} differs from the last build's {}",
                            r.primitive_count, l.range.primitive_count
                        )
                    }),
                Keep::FirstVertex => match (tri, range) {
                    (Some(t), Some(r))
                        if t.2 != IndexType::None && r.first_vertex != l.range.first_vertex =>
                    {
                        Some(format!(
                            "firstVertex {} differs from the last build's {}",
                            r.first_vertex, l.range.first_vertex
                        ))
                    }
                    _ => None,
                },
                Keep::InactiveStayInactive | Keep::ActiveStayActive => {
                    let Some(prims) = &now_prims else { continue };
                    let now: Vec<bool> = prims
                        .iter()
                        .filter(|p| p.geometry == j as u32)
                        .map(|p| p.active)
                        .collect();
                    let flip = now.iter().zip(&l.active).position(|(n, was)| {
                        if k == Keep::InactiveStayInactive {
                            *n && !*was
                        } else {
                            !*n && *was
                        }
                    });
                    flip.map(|p| {
                        format!(
                            "primitive {p} was {} and is now {}",
                            if k == Keep::InactiveStayInactive {
                                "inactive"
                            } else {
                                "active"
                            },
                            if k == Keep::InactiveStayInactive {
                                "active"
                            } else {
                                "inactive"
                            }
                        )
                    })
                }
                Keep::Dense(m) => match (&g.data, &l.dense) {
                    (GeometryData::DenseTrianglesAmdx(d), Some(ld)) => {
                        let f = |x: &super::call::DenseTriangles| match m {
                            0 => x.num_triangles as u64,
                            1 => x.num_vertices as u64,
                            2 => x.max_primitive_index as u64,
                            3 => x.max_geometry_index as u64,
                            4 => x.format as u64,
                            _ => x.data_size,
                        };
                        (f(d) != f(ld))
                            .then(|| "dense geometry member differs from the last build".into())
                    }
                    _ => None,
                },
                Keep::AllowUpdateBuilt
                | Keep::GeometryCount
                | Keep::Flags
                | Keep::StructureType => None,
            };
            if let Some(problem) = bad {
                push(out, gctx, problem);
            }
        }
    }
}

/// 03651: every range record the command reads lies in memory and is a valid
/// `VkAccelerationStructureBuildRangeInfoKHR` for its geometry (offset alignments by geometry kind).
fn check_range_records(cx: &Cx, out: &mut Out) {
    for (i, info) in cx.call.infos.iter().enumerate() {
        for (j, g) in info.geometries.iter().enumerate() {
            let ctx = format!("range record {j} of pInfos[{i}]");
            let Some(a) = cx.call.range_address(i, j) else {
                continue;
            };
            let Some(bytes) = cx.mem.read(&a, RangeInfo::SIZE) else {
                push(out, ctx, "lies outside every buffer of the world");
                continue;
            };
            let r = RangeInfo::from_bytes(bytes);
            let (what, m) = match &g.data {
                GeometryData::Triangles {
                    index_type: IndexType::None,
                    vertex_format,
                    ..
                } => ("primitiveOffset", vertex_format.component_size()),
                GeometryData::Triangles { index_type, .. } => {
                    ("primitiveOffset", index_type.size())
                }
                GeometryData::Aabbs { .. } => ("primitiveOffset", 8),
                GeometryData::Instances {
                    array_of_pointers: true,
                    ..
                } => ("primitiveOffset", 8),
                GeometryData::Instances { .. } => ("primitiveOffset", 16),
                _ => continue,
            };
            if r.primitive_offset as u64 % m != 0 {
                push(
                    out,
                    ctx.clone(),
                    format!("{what} {} is not a multiple of {m}", r.primitive_offset),
                );
            }
            if let GeometryData::Triangles { transform_data, .. } = &g.data {
                if !transform_data.is_null() && r.transform_offset % 16 != 0 {
                    push(
                        out,
                        ctx,
                        format!(
                            "transformOffset {} is not a multiple of 16",
                            r.transform_offset
                        ),
                    );
                }
            }
        }
    }
}

/// Offsets `delta` bytes into a symbolic address (re-exported for generators).
pub fn at(a: &Address, delta: u64) -> Address {
    offset(a, delta)
}
