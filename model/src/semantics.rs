//! What a valid launch does, per launch ID: which shader binding table record each ray reaches and so
//! which shader group writes the output (semantics.md §6, §7). The harness compares this with the
//! records the raygen shader wrote.

use crate::call::{Call, Table};
use crate::world::{GeometryKind, HandleRef, RayTarget, ShaderGroup, World};

/// Output word the harness pre-fills: the launch ID did not run.
pub const NOT_RUN: u32 = 0xFFFF_FFFF;
/// Output word when the ray was traced but no shader wrote the payload (zero group, or no closest-hit).
pub const UNTOUCHED: u32 = 0xFFFF_FFFE;
/// High half of the output word written by a miss shader of group `g`: `MISS_TAG | g`.
pub const MISS_TAG: u32 = 0x0001_0000;
/// High half of the output word written by a closest-hit shader of group `g`: `HIT_TAG | g`.
pub const HIT_TAG: u32 = 0x0002_0000;

/// The expected output of a valid launch: one word per launch ID, x fastest. Launch ID `id` traces ray
/// `id % rays`, so the output repeats with the rays' period and is held as one word per ray: the model
/// never allocates from the stated dimensions (an indirect command may state 2^96 invocations).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExpectedLaunch {
    pub dimensions: [u32; 3],
    /// The word of each ray; a single [`UNTOUCHED`] when the launch traces none.
    pub per_ray: Vec<u32>,
}

/// How a launch's output read back differs from the model's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputDifference {
    /// Another number of words than launch IDs.
    Length { got: u64, expected: u64 },
    /// The first launch ID whose word is not the model's.
    Word { id: u64, got: u32, expected: u32 },
}

impl ExpectedLaunch {
    /// The number of launch IDs (saturating at u64::MAX).
    pub fn invocations(&self) -> u64 {
        self.dimensions
            .iter()
            .map(|&d| d as u64)
            .fold(1, u64::saturating_mul)
    }

    /// The word launch ID `id` writes.
    pub fn word(&self, id: u64) -> u32 {
        self.per_ray[(id % self.per_ray.len() as u64) as usize]
    }

    /// How `got` (one word per launch ID, as read back) differs from the expected output: its length,
    /// or the first launch ID whose word is not the model's; None when it is the expected output.
    pub fn difference(&self, got: &[u32]) -> Option<OutputDifference> {
        if got.len() as u64 != self.invocations() {
            return Some(OutputDifference::Length {
                got: got.len() as u64,
                expected: self.invocations(),
            });
        }
        got.iter()
            .enumerate()
            .find(|(id, w)| **w != self.word(*id as u64))
            .map(|(id, w)| OutputDifference::Word {
                id: id as u64,
                got: *w,
                expected: self.word(id as u64),
            })
    }

    /// Every word, materialised: for launches as small as an output read back from a device.
    pub fn words(&self) -> Vec<u32> {
        (0..self.invocations()).map(|id| self.word(id)).collect()
    }
}

/// The miss record a ray reaches (`missIndex & 0xFFFF`, semantics.md §6).
pub fn miss_record(miss_index: u32) -> u64 {
    (miss_index & 0xFFFF) as u64
}

/// The hit record a ray reaches on geometry `geometry` of an instance with `instance_offset`.
pub fn hit_record(instance_offset: u32, geometry: u32, sbt_offset: u32, sbt_stride: u32) -> u64 {
    (instance_offset & 0xFF_FFFF) as u64
        + geometry as u64 * (sbt_stride & 0xF) as u64
        + (sbt_offset & 0xF) as u64
}

/// `base + stride * index`: where a record starts, or None past u64::MAX (where no buffer reaches).
fn at_record(base: u64, stride: u64, index: u64) -> Option<u64> {
    stride.checked_mul(index)?.checked_add(base)
}

/// The handle a table's record holds: (buffer, offset) resolved through the call's region or NV table.
pub fn record_handle(world: &World, call: &Call, table: Table, index: u64) -> Option<HandleRef> {
    match call {
        Call::TraceRaysNv(_) => {
            let t = call.nv_table(table)?;
            let stride = if table == Table::Raygen { 0 } else { t.stride };
            world.handle_at(t.buffer.as_deref()?, at_record(t.offset, stride, index)?)
        }
        _ => {
            let r = call.region(table)?;
            let (b, off) = r.address.buffer()?;
            world.handle_at(b, at_record(off, r.stride, index)?)
        }
    }
}

/// The word the launch writes for a ray, given the handles it reaches.
fn word_for_ray(world: &World, call: &Call, ray_index: usize) -> u32 {
    let ray = &world.launch.rays[ray_index];
    let pipeline = world.bound_pipeline();
    let group_of = |h: Option<HandleRef>| -> Option<u32> {
        match h {
            Some(HandleRef::Group(g)) => Some(g),
            _ => None,
        }
    };
    let miss = |world: &World| -> u32 {
        match group_of(record_handle(
            world,
            call,
            Table::Miss,
            miss_record(ray.miss_index),
        )) {
            Some(g) => MISS_TAG | g,
            None => UNTOUCHED,
        }
    };
    let RayTarget::Geometry { instance, geometry } = ray.target else {
        return miss(world);
    };
    let Some(inst) = world.launch.instances.get(instance as usize) else {
        return miss(world);
    };
    if inst.mask as u32 & ray.cull_mask & 0xFF == 0 {
        return miss(world);
    }
    let Some(kind) = inst.geometries.get(geometry as usize) else {
        return miss(world);
    };
    let idx = hit_record(
        inst.sbt_record_offset,
        geometry,
        ray.sbt_offset,
        ray.sbt_stride,
    );
    let group = group_of(record_handle(world, call, Table::Hit, idx));
    let shader_group = group.and_then(|g| pipeline?.groups.get(g as usize).copied());
    match (kind, shader_group) {
        // A procedural primitive is only hit when an intersection shader reports it.
        (
            GeometryKind::Aabbs,
            Some(ShaderGroup::ProceduralHit {
                intersection: true,
                closest_hit,
                ..
            }),
        ) => {
            if closest_hit {
                HIT_TAG | group.unwrap_or(0)
            } else {
                UNTOUCHED
            }
        }
        (GeometryKind::Aabbs, _) => miss(world),
        (
            GeometryKind::Triangles,
            Some(ShaderGroup::TrianglesHit {
                closest_hit: true, ..
            }),
        ) => HIT_TAG | group.unwrap_or(0),
        (GeometryKind::Triangles, _) => UNTOUCHED,
    }
}

/// Whether the bound pipeline's group `g` is a procedural hit group with an intersection shader: only
/// then is an AABB ever reported (semantics.md §3, §6: a zero group's intersection never reports).
fn reports_aabb(world: &World, group: Option<HandleRef>) -> bool {
    match group {
        Some(HandleRef::Group(g)) => matches!(
            world
                .bound_pipeline()
                .and_then(|p| p.groups.get(g as usize)),
            Some(ShaderGroup::ProceduralHit {
                intersection: true,
                ..
            })
        ),
        _ => false,
    }
}

/// Every shader binding table record the launch reads, as (table, record index), sorted: the raygen
/// record, the hit record of each ray that reaches geometry, the miss record of each ray that misses
/// (including rays at an AABB nothing reports), and the callable records executed. Empty when the
/// launch runs no invocation.
pub fn records_read(world: &World, call: &Call) -> Vec<(Table, u64)> {
    if call.dimensions(world).is_some_and(|d| d.contains(&0)) {
        return vec![];
    }
    let mut out = vec![(Table::Raygen, 0)];
    let launch = &world.launch;
    for ray in &launch.rays {
        let hit = match ray.target {
            RayTarget::Geometry { instance, geometry } => launch
                .instances
                .get(instance as usize)
                .filter(|inst| inst.mask as u32 & ray.cull_mask & 0xFF != 0)
                .and_then(|inst| Some((inst, *inst.geometries.get(geometry as usize)?, geometry))),
            RayTarget::Nothing => None,
        };
        match hit {
            Some((inst, kind, geometry)) => {
                let idx = hit_record(
                    inst.sbt_record_offset,
                    geometry,
                    ray.sbt_offset,
                    ray.sbt_stride,
                );
                out.push((Table::Hit, idx));
                if kind == GeometryKind::Aabbs
                    && !reports_aabb(world, record_handle(world, call, Table::Hit, idx))
                {
                    out.push((Table::Miss, miss_record(ray.miss_index)));
                }
            }
            None => out.push((Table::Miss, miss_record(ray.miss_index))),
        }
    }
    out.extend(
        launch
            .callables
            .iter()
            .map(|&c| (Table::Callable, c as u64)),
    );
    out.sort();
    out.dedup();
    out
}

/// The size of a shader group handle on a device: the profile's `shaderGroupHandleSize`, or 32, the
/// value the specification requires of every device with ray tracing pipelines.
pub fn handle_size(profile: &crate::DeviceProfile) -> u64 {
    profile.limit("shaderGroupHandleSize").unwrap_or(32)
}

/// Reads of the launch that the spec leaves undefined: a record in a null region, or past its region's
/// size (KHR) or its buffer's end (NV). A valid case must have none; the driver's output for such a
/// case is never judged.
pub fn undefined_reads(handle_size: u64, world: &World, call: &Call) -> Vec<String> {
    let mut out = Vec::new();
    for (table, index) in records_read(world, call) {
        match call {
            Call::TraceRaysNv(_) => {
                let Some(t) = call.nv_table(table) else {
                    continue;
                };
                let stride = if table == Table::Raygen { 0 } else { t.stride };
                let end =
                    at_record(t.offset, stride, index).and_then(|a| a.checked_add(handle_size));
                match t.buffer.as_deref().and_then(|b| world.buffer(b)) {
                    None => out.push(format!(
                        "{table:?} record {index} is read but the table has no buffer"
                    )),
                    Some(b) if end.is_none_or(|end| end > b.size) => out.push(format!(
                        "{table:?} record {index} ends at byte {}, past the end of `{}` ({} bytes)",
                        end.map_or("past u64::MAX".into(), |e| e.to_string()),
                        b.name,
                        b.size
                    )),
                    Some(_) => {}
                }
            }
            _ => {
                let Some(r) = call.region(table) else {
                    continue;
                };
                if r.address.is_null() {
                    out.push(format!(
                        "{table:?} record {index} is read but the region's address is null"
                    ));
                } else {
                    let end =
                        at_record(0, r.stride, index).and_then(|a| a.checked_add(handle_size));
                    match end {
                        Some(end) if end <= r.size => {}
                        Some(end) => out.push(format!(
                            "{table:?} record {index} ends at byte {end} of the region, past its size {}",
                            r.size
                        )),
                        None => out.push(format!(
                            "{table:?} record {index} ends past byte u64::MAX of the region"
                        )),
                    }
                }
            }
        }
    }
    out
}

/// The expected output words of a valid call, or None when the dimensions are not known.
pub fn expected_launch(world: &World, call: &Call) -> Option<ExpectedLaunch> {
    let dimensions = call.dimensions(world)?;
    let rays = world.launch.rays.len();
    let per_ray = if rays == 0 {
        vec![UNTOUCHED]
    } else {
        (0..rays).map(|r| word_for_ray(world, call, r)).collect()
    };
    Some(ExpectedLaunch {
        dimensions,
        per_ray,
    })
}
