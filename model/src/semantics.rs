//! What a valid launch does, per launch ID: which shader binding table records its ray may reach (the
//! reference tracer's candidates, semantics.md §6), which it reads, what is undefined, and the set of
//! records the shaders may write (`crate::tracer::AllowedOutcomes` per traced ray, judged against the
//! harness's `RayRecord`s in the session).

use crate::call::{Call, Table};
use crate::scene::{GeometryData, Ray, RayFlags, Scene};
use crate::tracer::{
    trace_ray, trace_rays, AllowedOutcomes, HitShaders, MissShader, PreparedScene, ShaderTable,
    TracerConfig, TracerStats,
};
use crate::world::{GeometryKind, HandleRef, ShaderGroup, World};
use std::collections::{BTreeSet, HashMap};
use std::hash::BuildHasherDefault;
use std::sync::{Arc, Mutex};

mod launch;
mod reads;
mod shapes;
use launch::{allowed_for_ray_memo, distinct_rays, HitRecordMemo};
pub use launch::{expected_launch, ExpectedLaunch, PerRay};
pub use reads::records_read;
#[cfg(test)]
pub(crate) use reads::{misses_by_tracing, misses_of};
pub use shapes::{shapes, CULLED_AABB_NULL_HIT_TABLE};

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

/// The number of launch IDs of a call (saturating at usize::MAX), when its dimensions are known.
pub fn launch_ids(world: &World, call: &Call) -> Option<usize> {
    call.dimensions(world)
        .map(|d| d.iter().map(|&x| x as usize).fold(1, usize::saturating_mul))
}

/// The rays a call traces: the first `min(launch IDs, rays)` of the launch's list (all of them when
/// the dimensions are not known).
pub fn traced_rays(world: &World, call: &Call) -> Vec<Ray> {
    world.launch.traced_rays(launch_ids(world, call))
}

/// The (instance, geometry) pairs of a scene one ray may reach a hit record from, whatever the shader
/// binding table holds: every triangle that may be a candidate after culling (the tracer's candidates),
/// and every procedural geometry of an instance the ray's mask and flags do not cull (boxes may be
/// enlarged without bound, so any of them may run its intersection shader).
pub fn ray_reach(prepared: &PreparedScene, ray: &Ray) -> Vec<(u32, u32, GeometryKind)> {
    let table = generic_table();
    let mut out: BTreeSet<(u32, u32, GeometryKind)> = BTreeSet::new();
    let mut stats = TracerStats::default();
    if let Ok(allowed) = trace_ray(prepared, ray, &table, &TracerConfig::default(), &mut stats) {
        out.extend(triangle_reach(&allowed));
    }
    out.extend(procedural_reach(prepared.scene(), ray));
    out.into_iter().collect()
}

/// The hit group [`ray_reach`] traces every geometry with: an intersection shader, no any-hit.
fn generic_hit(_: u32, _: u32) -> HitShaders {
    HitShaders::procedural(0, None)
}

/// The shader table of [`ray_reach`]: [`generic_hit`] everywhere.
fn generic_table() -> ShaderTable<'static> {
    ShaderTable {
        hit: &generic_hit,
        miss: MissShader {
            zero_group: false,
            group: 0,
        },
    }
}

/// The triangle half of [`ray_reach`]: the (instance, geometry) of every triangle candidate.
fn triangle_reach(
    allowed: &AllowedOutcomes,
) -> impl Iterator<Item = (u32, u32, GeometryKind)> + '_ {
    allowed
        .candidates
        .iter()
        .filter(|c| c.kind == crate::tracer::PrimitiveKind::Triangle && !c.behind_shaderless_cut)
        .map(|c| {
            (
                c.primitive.instance,
                c.primitive.geometry,
                GeometryKind::Triangles,
            )
        })
}

/// The procedural half of [`ray_reach`]: every procedural geometry with an active box of an instance
/// the ray's mask and flags do not cull (no tracing needed).
fn procedural_reach(scene: &Scene, ray: &Ray) -> Vec<(u32, u32, GeometryKind)> {
    procedural_geometries(scene, ray)
        .filter(|&(_, _, culled)| !culled)
        .map(|(i, g, _)| (i, g, GeometryKind::Aabbs))
        .collect()
}

/// Every procedural geometry with an active box in an instance the ray's cull mask admits, unless
/// the ray skips AABBs, as (instance, geometry, whether the ray's opacity flags cull it).
fn procedural_geometries<'a>(
    scene: &'a Scene,
    ray: &'a Ray,
) -> impl Iterator<Item = (u32, u32, bool)> + 'a {
    let skips = ray.flags.contains(RayFlags::SKIP_AABBS);
    scene
        .instances
        .iter()
        .enumerate()
        .filter(move |(_, inst)| !skips && inst.mask as u32 & ray.cull_mask & 0xFF != 0)
        .filter_map(|(i, inst)| Some((i, inst, inst.bottom_level?)))
        .flat_map(move |(i, inst, b)| {
            scene.bottom_levels[b as usize]
                .geometries
                .iter()
                .enumerate()
                .filter_map(move |(g, geometry)| {
                    let GeometryData::Aabbs(a) = &geometry.data else {
                        return None;
                    };
                    if a.boxes.iter().all(|b| b.is_inactive()) {
                        return None;
                    }
                    let opaque = crate::tracer::opacity(ray, inst, geometry.flags.opaque);
                    let culled = crate::tracer::opacity_culled(ray, opaque);
                    Some((i as u32, g as u32, culled))
                })
        })
}

/// A hash of a scene's content (bit patterns), the key of the prepared-scene memo.
pub fn scene_key(scene: &Scene) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    // serde_json of the scene would do, but costs an allocation of its whole text; bincode-like by hand.
    for bl in &scene.bottom_levels {
        0xB1u8.hash(&mut h);
        for g in &bl.geometries {
            (g.flags.opaque, g.flags.no_duplicate_any_hit).hash(&mut h);
            match &g.data {
                GeometryData::Triangles(t) => {
                    1u8.hash(&mut h);
                    for p in &t.positions {
                        p.map(f32::to_bits).hash(&mut h);
                    }
                    match &t.indices {
                        Some(crate::scene::Indices::U16(v)) => (16u8, v).hash(&mut h),
                        Some(crate::scene::Indices::U32(v)) => (32u8, v).hash(&mut h),
                        None => 0u8.hash(&mut h),
                    }
                    if let Some(m) = &t.transform {
                        m.0.map(|r| r.map(f32::to_bits)).hash(&mut h);
                    }
                }
                GeometryData::Aabbs(a) => {
                    2u8.hash(&mut h);
                    for b in &a.boxes {
                        (b.min.map(f32::to_bits), b.max.map(f32::to_bits)).hash(&mut h);
                    }
                    for s in &a.spheres {
                        (s.center.map(f32::to_bits), s.radius.to_bits()).hash(&mut h);
                    }
                }
            }
        }
    }
    for inst in &scene.instances {
        (
            inst.bottom_level,
            inst.transform.0.map(|r| r.map(f32::to_bits)),
            inst.custom_index,
            inst.mask,
            inst.sbt_record_offset,
        )
            .hash(&mut h);
        let f = inst.flags;
        (
            f.triangle_facing_cull_disable,
            f.flip_facing,
            f.force_opaque,
            f.force_no_opaque,
        )
            .hash(&mut h);
    }
    h.finish()
}

/// The bits of a ray, the key of per-ray memos.
pub fn ray_key(r: &Ray) -> [u32; 13] {
    let o = r.origin.map(f32::to_bits);
    let d = r.direction.map(f32::to_bits);
    [
        o[0],
        o[1],
        o[2],
        d[0],
        d[1],
        d[2],
        r.tmin.to_bits(),
        r.tmax.to_bits(),
        r.flags.0,
        r.cull_mask,
        r.sbt_offset,
        r.sbt_stride,
        r.miss_index,
    ]
}

/// Prepared scenes by content, shared by every judgement of a case (the generator, the gate, the rules
/// and the comparison each ask), the most recently asked kept within `KEPT_SCENES` and
/// `KEPT_ITEMS`: a run generates a spec's cases (up to 512) before its gate traces them, so a
/// budget of a few scenes had each scene prepared twice. A scene is found by comparing it bit for
/// bit with the prepared ones' (one pass over its data, no hash to collide).
pub fn prepared(scene: &Scene) -> Option<Arc<PreparedScene>> {
    static MEMO: Mutex<Vec<Arc<PreparedScene>>> = Mutex::new(Vec::new());
    let mut memo = MEMO.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(pos) = memo.iter().rposition(|p| same_scene(p.scene(), scene)) {
        let hit = memo.remove(pos);
        memo.push(hit.clone());
        return Some(hit);
    }
    let p = Arc::new(PreparedScene::new(scene).ok()?);
    memo.push(p.clone());
    // The least recently asked go first; the newest stays whatever its size.
    let mut items: usize = memo.iter().map(|p| p.items.len()).sum();
    while memo.len() > 1 && (memo.len() > KEPT_SCENES || items > KEPT_ITEMS) {
        items -= memo.remove(0).items.len();
    }
    Some(p)
}

/// The most prepared scenes [`prepared`] keeps.
const KEPT_SCENES: usize = 1024;

/// The most primitives [`prepared`] keeps prepared in all, a few hundred bytes each: the default
/// conformance run's scenes add about 15 MB to the runner.
const KEPT_ITEMS: usize = 1 << 19;

/// Whether two scenes are identical bit for bit (−0 and +0 differ, a NaN equals the same NaN).
pub fn same_scene(a: &Scene, b: &Scene) -> bool {
    fn floats(a: &[f32], b: &[f32]) -> bool {
        /// The bytes of the floats (their bits in memory order), compared as one block.
        fn bytes(v: &[f32]) -> &[u8] {
            // SAFETY: an f32 is four initialised bytes without padding; u8 needs no alignment, and
            // the slice covers exactly the floats' memory.
            unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<u8>(), std::mem::size_of_val(v)) }
        }
        a.len() == b.len() && bytes(a) == bytes(b)
    }
    fn transform(a: &crate::scene::Transform3x4, b: &crate::scene::Transform3x4) -> bool {
        floats(a.0.as_flattened(), b.0.as_flattened())
    }
    let (
        Scene {
            bottom_levels: la,
            instances: ia,
        },
        Scene {
            bottom_levels: lb,
            instances: ib,
        },
    ) = (a, b);
    let levels = la.len() == lb.len()
        && la.iter().zip(lb).all(|(x, y)| {
            let (
                crate::scene::BottomLevel { geometries: gx },
                crate::scene::BottomLevel { geometries: gy },
            ) = (x, y);
            gx.len() == gy.len()
                && gx.iter().zip(gy).all(|(g, h)| {
                    let (
                        crate::scene::Geometry {
                            flags: fg,
                            data: dg,
                        },
                        crate::scene::Geometry {
                            flags: fh,
                            data: dh,
                        },
                    ) = (g, h);
                    fg == fh
                        && match (dg, dh) {
                            (GeometryData::Triangles(t), GeometryData::Triangles(u)) => {
                                let crate::scene::Triangles {
                                    positions: pt,
                                    indices: it,
                                    transform: tt,
                                } = t;
                                let crate::scene::Triangles {
                                    positions: pu,
                                    indices: iu,
                                    transform: tu,
                                } = u;
                                floats(pt.as_flattened(), pu.as_flattened())
                                    && it == iu
                                    && match (tt, tu) {
                                        (Some(m), Some(n)) => transform(m, n),
                                        (None, None) => true,
                                        _ => false,
                                    }
                            }
                            (GeometryData::Aabbs(x), GeometryData::Aabbs(y)) => {
                                let crate::scene::Aabbs {
                                    boxes: bx,
                                    spheres: sx,
                                } = x;
                                let crate::scene::Aabbs {
                                    boxes: by,
                                    spheres: sy,
                                } = y;
                                bx.len() == by.len()
                                    && bx.iter().zip(by).all(|(p, q)| {
                                        floats(&p.min, &q.min) && floats(&p.max, &q.max)
                                    })
                                    && sx.len() == sy.len()
                                    && sx.iter().zip(sy).all(|(p, q)| {
                                        floats(&p.center, &q.center)
                                            && p.radius.to_bits() == q.radius.to_bits()
                                    })
                            }
                            _ => false,
                        }
                })
        });
    levels
        && ia.len() == ib.len()
        && ia.iter().zip(ib).all(|(x, y)| {
            let crate::scene::SceneInstance {
                bottom_level,
                transform: t,
                custom_index,
                mask,
                sbt_record_offset,
                flags,
            } = x;
            *bottom_level == y.bottom_level
                && transform(t, &y.transform)
                && *custom_index == y.custom_index
                && *mask == y.mask
                && *sbt_record_offset == y.sbt_record_offset
                && *flags == y.flags
        })
}

/// The hit records the launch may read, with the kind of geometry each is reached from, sorted: the
/// union over the traced rays of [`ray_reach`] (shader-independent). Empty when the launch runs no
/// invocation or its scene is undefined (then the case is refused before anything reads it).
pub fn reached_hit_records(world: &World, call: &Call) -> Vec<(u64, GeometryKind)> {
    match launch_ids(world, call) {
        Some(0) => vec![],
        ids => launch_hit_reach(&world.launch, ids),
    }
}

/// [`reached_hit_records`] of a launch of `ids` launch IDs (None: every ray of the list).
pub fn launch_hit_reach(
    launch: &crate::world::Launch,
    ids: Option<usize>,
) -> Vec<(u64, GeometryKind)> {
    HIT_REACH.get_or(reach_key(launch, ids), || {
        let rays = launch.traced_rays(ids);
        if rays.is_empty() {
            return vec![];
        }
        traced_hit_reach(launch, &rays)
    })
}

/// The key [`HIT_REACH`] keeps a launch's reach by: the fingerprint of its scene and of what its
/// traced rays are made of — the explicit rays (their [`ray_key`]s), the camera and the launch size,
/// of which [`crate::world::Launch::traced_rays`] is a function —, so a lookup makes no camera ray.
fn reach_key(launch: &crate::world::Launch, ids: Option<usize>) -> Option<u128> {
    let keys: Vec<[u32; 13]> = launch.rays.iter().map(ray_key).collect();
    crate::fingerprint::of_with_words(&(&launch.scene, &launch.camera, ids), keys.as_flattened())
}

/// Launches' hit reach by [`reach_key`]: the generator, the gate,
/// the rules and the judgement of one case each ask for the same launch's reach, the generator and
/// the gate a whole chunk of cases apart; a launch traced once (or its reach found from its allowed
/// outcomes, [`prime_hit_reach`]) serves them all.
static HIT_REACH: crate::fingerprint::Memo<Vec<(u64, GeometryKind)>, 4096> =
    crate::fingerprint::Memo::new();

/// Keeps a valid launch's [`reached_hit_records`] found from its allowed outcomes, so the gate does
/// not trace the launch a second time with the generic table [`ray_reach`] uses. The triangles a
/// trace keeps as candidates depend on the shader table only through its cut
/// (`tracer::cut_allowed_for`): the generic table (no any-hit anywhere) allows the cut wherever
/// the ray may not end at its first hit, and where the launch's own table does not (a non-opaque
/// geometry with any-hit), its outcomes mark the candidates the generic cut leaves out
/// (`Candidate::behind_shaderless_cut`). The procedural half needs no tracing.
pub fn prime_hit_reach(world: &World, call: &Call, expected: &ExpectedLaunch) {
    if launch_ids(world, call) == Some(0) {
        return;
    }
    if let Some(reach) = derived_hit_reach(world, expected) {
        // The outcomes are of the rays `traced_rays` gives for the call's launch IDs.
        let key = reach_key(&world.launch, launch_ids(world, call));
        let _ = HIT_REACH.get_or(key, || reach);
    }
}

/// [`traced_hit_reach`] of the launch's rays found from their allowed outcomes (see
/// [`prime_hit_reach`]), or None where the outcomes are not every ray's.
fn derived_hit_reach(world: &World, expected: &ExpectedLaunch) -> Option<Vec<(u64, GeometryKind)>> {
    if expected.rays.is_empty() || expected.allowed.len() != expected.rays.len() {
        return None;
    }
    let scene = &world.launch.scene;
    Some(hit_reach_of(scene, &expected.rays, |k, ray| {
        triangle_reach(&expected.allowed[k]).chain(procedural_reach(scene, ray))
    }))
}

/// [`launch_hit_reach`] traced: the union of the distinct rays' [`ray_reach`] as hit records. A scene
/// without triangle geometry needs no tracing: every candidate a trace could find is procedural,
/// which [`triangle_reach`] leaves out, so each ray's reach is its [`procedural_reach`] alone (a
/// procedural scene's trace classifies every sphere of every box the ray meets, the most costly
/// part of generating its case).
fn traced_hit_reach(launch: &crate::world::Launch, rays: &[Ray]) -> Vec<(u64, GeometryKind)> {
    let Some(prepared) = prepared(&launch.scene) else {
        return vec![];
    };
    if !has_triangle_geometry(&launch.scene) {
        return hit_reach_of(&launch.scene, rays, |_, ray| {
            procedural_reach(&launch.scene, ray)
        });
    }
    // Every distinct ray traced with the generic table at once (`trace_rays` walks several rays in
    // turn), each one's reach as `ray_reach` gives it: its triangle candidates and its procedural half.
    let (distinct, _) = distinct_rays(rays);
    let table = generic_table();
    let pairs: Vec<(&Ray, &ShaderTable)> = distinct
        .iter()
        .map(|&k| (&rays[k as usize], &table))
        .collect();
    let mut triangles: Vec<Vec<(u32, u32, GeometryKind)>> = vec![Vec::new(); rays.len()];
    let mut stats = TracerStats::default();
    trace_rays(
        &prepared,
        &pairs,
        &TracerConfig::default(),
        &mut stats,
        |j, a| {
            if let Ok(allowed) = a {
                triangles[distinct[j] as usize] = triangle_reach(&allowed).collect();
            }
        },
    );
    hit_reach_of_distinct(&launch.scene, rays, &distinct, |k, ray| {
        std::mem::take(&mut triangles[k])
            .into_iter()
            .chain(procedural_reach(&launch.scene, ray))
    })
}

/// Whether any bottom level an instance uses holds triangle geometry (the only kind a trace adds to
/// a ray's reach).
fn has_triangle_geometry(scene: &Scene) -> bool {
    scene
        .instances
        .iter()
        .filter_map(|inst| inst.bottom_level)
        .filter_map(|b| scene.bottom_levels.get(b as usize))
        .flat_map(|bl| &bl.geometries)
        .any(|g| matches!(g.data, GeometryData::Triangles(_)))
}

/// The hit records of the (instance, geometry, kind) triples `reach` gives for each distinct ray
/// ([`distinct_rays`]; `reach` gets the ray's index in `rays`).
fn hit_reach_of<R: IntoIterator<Item = (u32, u32, GeometryKind)>>(
    scene: &Scene,
    rays: &[Ray],
    reach: impl FnMut(usize, &Ray) -> R,
) -> Vec<(u64, GeometryKind)> {
    hit_reach_of_distinct(scene, rays, &distinct_rays(rays).0, reach)
}

/// [`hit_reach_of`] with the distinct rays' indices already found.
fn hit_reach_of_distinct<R: IntoIterator<Item = (u32, u32, GeometryKind)>>(
    scene: &Scene,
    rays: &[Ray],
    distinct: &[u32],
    mut reach: impl FnMut(usize, &Ray) -> R,
) -> Vec<(u64, GeometryKind)> {
    let mut out: BTreeSet<(u64, GeometryKind)> = BTreeSet::new();
    for &k in distinct {
        let k = k as usize;
        let ray = &rays[k];
        for (i, g, kind) in reach(k, ray) {
            let inst = &scene.instances[i as usize];
            out.insert((
                hit_record(inst.sbt_record_offset, g, ray.sbt_offset, ray.sbt_stride),
                kind,
            ));
        }
    }
    out.into_iter().collect()
}

/// The shader group a hit record holds, as the tracer sees it: a zero handle is the zero group; a
/// handle the pipeline cannot resolve (foreign, unwritten, not a hit group) is treated as zero too —
/// such a case is invalid and its output never judged.
pub fn hit_shaders(world: &World, call: &Call, index: u64) -> HitShaders {
    let group = match record_handle(world, call, Table::Hit, index) {
        Some(HandleRef::Group(g)) => g,
        _ => return HitShaders::zero(),
    };
    match world
        .bound_pipeline()
        .and_then(|p| p.groups.get(group as usize))
    {
        Some(ShaderGroup::TrianglesHit {
            closest_hit,
            any_hit,
            any_hit_rule,
        }) => HitShaders {
            zero_group: false,
            closest_hit: *closest_hit,
            any_hit: any_hit.then_some(*any_hit_rule),
            intersection: false,
            group,
        },
        Some(ShaderGroup::ProceduralHit {
            closest_hit,
            any_hit,
            any_hit_rule,
            intersection,
        }) => HitShaders {
            zero_group: false,
            closest_hit: *closest_hit,
            any_hit: any_hit.then_some(*any_hit_rule),
            intersection: *intersection,
            group,
        },
        _ => HitShaders::zero(),
    }
}

/// The miss shader a miss record holds (unresolvable handles as the zero group, as for hits).
pub fn miss_shader(world: &World, call: &Call, index: u64) -> MissShader {
    match record_handle(world, call, Table::Miss, index) {
        Some(HandleRef::Group(g)) => MissShader {
            zero_group: false,
            group: g,
        },
        _ => MissShader {
            zero_group: true,
            group: 0,
        },
    }
}

/// The outcomes the spec allows for one ray of the launch, with the shader binding table resolved
/// through the case's records.
pub fn allowed_for_ray(
    world: &World,
    call: &Call,
    prepared: &PreparedScene,
    ray: &Ray,
    stats: &mut TracerStats,
) -> Option<AllowedOutcomes> {
    allowed_for_ray_with(world, call, prepared, ray, &TracerConfig::default(), stats)
}

/// [`allowed_for_ray`] with other tracer settings (brute force: the reference of the default).
pub fn allowed_for_ray_with(
    world: &World,
    call: &Call,
    prepared: &PreparedScene,
    ray: &Ray,
    config: &TracerConfig,
    stats: &mut TracerStats,
) -> Option<AllowedOutcomes> {
    let memo = HitRecordMemo::default();
    allowed_for_ray_memo(world, call, prepared, ray, config, stats, &memo)
}

/// The recursion depth the launch reaches (see [`crate::world::Launch::recursion_depth`]): 0 when it
/// traces no ray or runs no invocation, 1 when raygen traces, and 1 + `extra_recursion` only when some
/// ray can run a closest-hit shader — the one shader that traces again: some hit record a traced ray
/// can reach ([`reached_hit_records`]) holds a group with a closest-hit shader. A launch whose rays
/// reach only zero groups or hit groups without closest-hit (or nothing) stops at depth 1.
pub fn recursion_depth(world: &World, call: &Call) -> u32 {
    let launch = &world.launch;
    if !launch.traces() || launch_ids(world, call) == Some(0) {
        return 0;
    }
    let closest_hit_runs = reached_hit_records(world, call).iter().any(|&(index, _)| {
        let h = hit_shaders(world, call, index);
        !h.zero_group && h.closest_hit
    });
    if closest_hit_runs {
        launch.recursion_depth()
    } else {
        1
    }
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

#[cfg(test)]
mod hit_reach_tests {
    use super::*;
    use crate::test_cases::hand_case;

    /// Hit records with the kind of geometry they are reached from.
    type Reach = Vec<(u64, GeometryKind)>;

    /// The traced reach of a valid case's launch (what the gate computed before the outcomes could
    /// tell it), and the reach found from the outcomes, where they may.
    fn both(t: &crate::TraceBody) -> Option<(Reach, Option<Reach>)> {
        let e = expected_launch(&t.world, &t.call)?;
        let traced = traced_hit_reach(&t.world.launch, &e.rays);
        Some((traced, derived_hit_reach(&t.world, &e)))
    }

    #[test]
    fn the_reach_found_from_the_outcomes_is_the_traced_reach() {
        let mut found = 0;
        let mut traced_only = 0;
        let mut bodies: Vec<(String, crate::TraceBody)> = Vec::new();
        for path in crate::test_cases::repository_case_files() {
            let Ok(text) = std::fs::read_to_string(&path) else {
                continue;
            };
            let Ok(case) = crate::Case::from_yaml("repo", &text) else {
                continue;
            };
            if case.intent != crate::Intent::Valid {
                continue;
            }
            if let Some(t) = case.as_trace() {
                bodies.push((path.display().to_string(), t.clone()));
            }
        }
        // The standard workloads as launches of the hand-made case, with rays that cull, skip, end
        // at their first hit or are forced opaque or non-opaque, so the cut and the culling vary;
        // and with an any-hit shader in the hit group (procedural for the spheres), so that
        // non-opaque triangles take the launch's own cut away where the generic table keeps it.
        use crate::tracer::AnyHitRule;
        for w in crate::tracer::workload::standard_workloads(8, false) {
            for any_hit in [None, Some(AnyHitRule::Accept), Some(AnyHitRule::Terminate)] {
                for flags in [
                    0u32, 0x1, 0x2, 0x4, 0x10, 0x20, 0x40, 0x80, 0x100, 0x200, 0x12,
                ] {
                    let mut case = w.as_launch_of(hand_case(), 8);
                    let t = case.as_trace_mut().expect("a trace case");
                    for r in &mut t.world.launch.rays {
                        r.flags = crate::scene::RayFlags(flags);
                    }
                    if let Some(rule) = any_hit {
                        let pipeline = t.world.pipeline.as_mut().expect("a pipeline");
                        for g in &mut pipeline.groups {
                            if let crate::world::ShaderGroup::TrianglesHit {
                                any_hit,
                                any_hit_rule,
                                ..
                            }
                            | crate::world::ShaderGroup::ProceduralHit {
                                any_hit,
                                any_hit_rule,
                                ..
                            } = g
                            {
                                (*any_hit, *any_hit_rule) = (true, rule);
                            }
                        }
                    }
                    let what = format!("{} flags {flags:#x} any-hit {any_hit:?}", w.name);
                    bodies.push((what, t.clone()));
                }
            }
        }
        // Launches whose outcomes left some candidate behind the generic table's cut.
        let mut marked = 0;
        for (what, t) in &bodies {
            let Some((traced, derived)) = both(t) else {
                continue;
            };
            let e = expected_launch(&t.world, &t.call).expect("traced above");
            if e.allowed
                .iter()
                .any(|a| a.candidates.iter().any(|c| c.behind_shaderless_cut))
            {
                marked += 1;
            }
            match derived {
                Some(d) => {
                    assert_eq!(d, traced, "{what}");
                    found += 1;
                }
                None => traced_only += 1,
            }
        }
        assert!(
            found >= 40 && traced_only == 0,
            "{found} launches compared ({traced_only} left to tracing)"
        );
        assert!(
            marked >= 5,
            "{marked} launches had candidates behind the generic table's cut"
        );
    }

    #[test]
    fn a_scene_without_triangles_reaches_what_its_trace_reaches() {
        // Spheres in boxes seen by cameras inside and outside the boxes, with rays that cull, skip
        // or end at their first hit, and instances whose masks the rays' cull masks miss: the reach
        // found without tracing is the traced one.
        let mut compared = 0;
        for seed in 0..6u64 {
            let bl = crate::scene::build::spheres_in_boxes(seed, 40 + 30 * seed as usize, 3.0, 0.4);
            let mut scene = Scene {
                bottom_levels: vec![bl],
                instances: crate::scene::build::instanced_copies(seed, 0, 3, 7.0),
            };
            for (k, inst) in scene.instances.iter_mut().enumerate() {
                inst.mask = if k == 1 { 0x02 } else { 0xFF };
            }
            assert!(!has_triangle_geometry(&scene));
            let prepared = crate::tracer::PreparedScene::new(&scene).expect("a defined scene");
            for (eye, flags, cull) in [
                ([9.0, 7.0, 5.0], 0u32, 0xFF),
                ([0.5, 0.2, 0.1], 0x4, 0xFF),
                ([-8.0, 3.0, 2.0], 0x200, 0x01),
                ([4.0, -9.0, 6.0], 0x20, 0xFF),
            ] {
                let mut rays =
                    crate::scene::build::pinhole_rays(12, 12, eye, [0.0; 3], [0.0, 0.0, 1.0], 0.9);
                for r in &mut rays {
                    r.flags = crate::scene::RayFlags(flags);
                    r.cull_mask = cull;
                }
                let traced = hit_reach_of(&scene, &rays, |_, ray| ray_reach(&prepared, ray));
                let found = hit_reach_of(&scene, &rays, |_, ray| procedural_reach(&scene, ray));
                assert_eq!(found, traced, "seed {seed}, eye {eye:?}, flags {flags:#x}");
                compared += 1;
            }
        }
        assert_eq!(compared, 24);
        // Where a scene has triangles the shortcut would be wrong: the trace adds what the
        // procedural half cannot know.
        let w = &crate::tracer::workload::standard_workloads(8, false)[1];
        assert!(has_triangle_geometry(&w.scene));
        let prepared = crate::tracer::PreparedScene::new(&w.scene).expect("a defined scene");
        let traced = hit_reach_of(&w.scene, &w.rays, |_, ray| ray_reach(&prepared, ray));
        let procedural = hit_reach_of(&w.scene, &w.rays, |_, ray| procedural_reach(&w.scene, ray));
        assert!(procedural.is_empty() && !traced.is_empty());
    }

    #[test]
    fn a_record_only_behind_the_generic_cut_is_not_reached() {
        // Two instances of a 4x4 grid, the near one (record 0) larger than the camera's view, no
        // ray through its edges, and the far one (record 1) behind it, both non-opaque, the hit group with an any-hit shader:
        // the launch's own trace keeps the far instance's triangles, but the generic table's
        // trace cuts behind the near hit on every ray, so record 1 is not reached — only the
        // candidates' marks keep it out of the reach found from the outcomes.
        use crate::scene::{build, SceneInstance, Transform3x4};
        let mut bl = build::grid(4, 4, 1.0);
        bl.geometries[0].flags.opaque = false;
        let at = |s: f32, [x, y, z]: [f32; 3], record: u32| SceneInstance {
            transform: Transform3x4([[s, 0.0, 0.0, x], [0.0, s, 0.0, y], [0.0, 0.0, s, z]]),
            sbt_record_offset: record,
            ..SceneInstance::of(0)
        };
        let w = crate::tracer::workload::Workload {
            name: "occluded",
            scene: Scene {
                bottom_levels: vec![bl],
                instances: vec![
                    at(4.0, [-8.3, -7.9, 1.0], 0),
                    at(1.0, [-2.0, -2.0, -1.0], 1),
                ],
            },
            rays: build::pinhole_rays(8, 8, [0.0, 0.0, 6.0], [0.0; 3], [0.0, 1.0, 0.0], 0.9),
        };
        let mut case = w.as_launch_of(hand_case(), 8);
        let t = case.as_trace_mut().expect("a trace case");
        let p = t.world.pipeline.as_mut().expect("a pipeline");
        for g in &mut p.groups {
            if let crate::world::ShaderGroup::TrianglesHit { any_hit, .. } = g {
                *any_hit = true;
            }
        }
        let (traced, derived) = both(t).expect("the launch's outcomes");
        let records = |r: &Reach| r.iter().map(|&(record, _)| record).collect::<Vec<_>>();
        assert_eq!(records(&traced), vec![0]);
        assert_eq!(derived, Some(traced));
        // The marks are what keeps record 1 out: the far instance's triangles are candidates.
        let e = expected_launch(&t.world, &t.call).expect("the launch's outcomes");
        let far_kept = e.allowed.iter().flat_map(|a| &a.candidates);
        let far_kept: Vec<_> = far_kept.filter(|c| c.primitive.instance == 1).collect();
        assert!(!far_kept.is_empty());
        assert!(far_kept.iter().all(|c| c.behind_shaderless_cut));
    }

    #[test]
    fn an_any_hit_shader_on_a_non_opaque_geometry_marks_what_the_generic_cut_leaves_out() {
        // The hand case with its hit group given an any-hit shader and its geometries made
        // non-opaque: the launch's own table forbids the cut the generic one makes, so its outcomes
        // keep triangles behind the nearest required hit, marked; without them the reach is the
        // traced one.
        let w = &crate::tracer::workload::standard_workloads(8, false)[1];
        let mut case = w.as_launch_of(hand_case(), 8);
        let t = case.as_trace_mut().expect("a trace case");
        for bl in &mut t.world.launch.scene.bottom_levels {
            for g in &mut bl.geometries {
                g.flags.opaque = false;
            }
        }
        let p = t
            .world
            .pipeline
            .as_mut()
            .expect("the hand case has a pipeline");
        for g in &mut p.groups {
            if let crate::world::ShaderGroup::TrianglesHit { any_hit, .. } = g {
                *any_hit = true;
            }
        }
        let (traced, derived) = both(t).expect("the launch's outcomes");
        assert!(!traced.is_empty());
        assert_eq!(derived, Some(traced));
        let e = expected_launch(&t.world, &t.call).expect("the launch's outcomes");
        let marked: usize = e
            .allowed
            .iter()
            .map(|a| {
                a.candidates
                    .iter()
                    .filter(|c| c.behind_shaderless_cut)
                    .count()
            })
            .sum();
        let kept: usize = e.allowed.iter().map(|a| a.candidates.len()).sum();
        assert!(
            marked > 0 && marked < kept,
            "{marked} of {kept} candidates behind the generic cut"
        );
    }
}
