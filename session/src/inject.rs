//! Seeded faults that measure how small a driver deviation the suite finds: [`inject`] makes the copy
//! of a valid trace case that the harness executes in place of the case the model judges — a vertex
//! moved by k ULPs, an instance transform perturbed by a relative e, a shader binding table region's
//! stride or base moved by k handles, the rays' cull mask with k bits flipped, k primitives dropped,
//! every hit's t biased by a relative e. The copy is what a driver with that fault would have done
//! with the original; the model keeps the original, so a caught fault is a failing case.
//!
//! Every choice (which vertex, instance, region, bits) is drawn from the seed and the case's name, and
//! only among what the launch observes (a primitive some ray must hit, a record some ray's output shows, a mask
//! bit that changes which instances a ray sees): a fault nothing can observe is an equivalent mutant
//! and reported [`NotApplicable`], as is a case the kind has nothing to act on. Size 0 is the case
//! itself, unchanged. Whether the copy may reach a driver is the gate's to say (`gate.rs`): a copy the
//! model judges invalid is not applicable either, so the layer stays quiet and only output decides.

use model::call::{Call, StridedRegion, Table};
use model::scene::build::SceneRng;
use model::scene::{GeometryData, Indices, Ray};
use model::tracer::PrimitiveRef;
use model::world::{HandleRef, World};
use model::{Case, DeviceProfile, Intent};
use std::fmt;

/// What an injection perturbs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Kind {
    /// One vertex of a triangle some ray must hit, moved k ULPs along its largest axis.
    VertexUlps,
    /// The 12 entries of an instance some ray must hit, each moved by `e · max(|entry|, scale)`.
    InstanceTransform,
    /// The stride of the hit or miss region, plus k handle sizes, where a ray's record shows a
    /// record ≥ 1 of it.
    SbtStride,
    /// The base of the hit or miss region, moved by k handle sizes (rounded up to the profile's
    /// `shaderGroupBaseAlignment`), where a ray's record shows a record of it.
    SbtOffset,
    /// k bits of every ray's cull mask flipped.
    CullMask,
    /// k primitives some ray must hit dropped (a triangle made degenerate, a box made inactive; the
    /// primitive count and every PrimitiveID stay).
    DropPrimitive,
    /// Every ray that must hit starts `e · t` further along its direction: its reported t is short
    /// by a relative e.
    TBias,
}

impl Kind {
    pub const ALL: [Kind; 7] = [
        Kind::VertexUlps,
        Kind::InstanceTransform,
        Kind::SbtStride,
        Kind::SbtOffset,
        Kind::CullMask,
        Kind::DropPrimitive,
        Kind::TBias,
    ];

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Kind::VertexUlps => "vertex-ulps",
            Kind::InstanceTransform => "instance-transform",
            Kind::SbtStride => "sbt-stride",
            Kind::SbtOffset => "sbt-offset",
            Kind::CullMask => "cull-mask",
            Kind::DropPrimitive => "drop-primitive",
            Kind::TBias => "t-bias",
        }
    }

    pub fn parse(name: &str) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// What the size counts.
    pub fn unit(self) -> &'static str {
        match self {
            Kind::VertexUlps => "ULPs",
            Kind::InstanceTransform | Kind::TBias => "relative",
            Kind::SbtStride | Kind::SbtOffset => "handles",
            Kind::CullMask => "bits",
            Kind::DropPrimitive => "primitives",
        }
    }

    /// Whether sizes are whole numbers (and the largest size accepted).
    fn whole(self) -> Option<u64> {
        match self {
            Kind::VertexUlps => Some(1 << 24),
            Kind::SbtStride | Kind::SbtOffset => Some(64),
            Kind::CullMask => Some(8),
            Kind::DropPrimitive => Some(1 << 16),
            Kind::InstanceTransform | Kind::TBias => None,
        }
    }

    /// The smallest size the suite is meant to catch: below it the fault lies within what the
    /// reference tracer allows a conformant f32 implementation (its VARY band, `model::tracer::band`),
    /// so no oracle may call it a failure. The mutation score counts sizes at or above it.
    ///
    /// The band moves each of a triangle's three vertices, the ray's origin and its direction by up
    /// to `BAND_SAFETY_FACTOR · ETA_TEST = 128u` of their distance from the origin (u the f32 unit
    /// roundoff), plus the instance inverse's error; [`BAND_TERMS`] counts those terms. The rendered
    /// scenes' rays start up to 12 units from geometry whose vertices' largest coordinates are at
    /// least about 0.3 ([`DISTANCE_RATIO`] bounds distance over magnitude). A relative error the band
    /// always absorbs is therefore `128u · BAND_TERMS · DISTANCE_RATIO` ([`REL_THRESHOLD`], about
    /// 2.4e-3), and:
    /// - a vertex moved k ULPs of its largest coordinate moves more than `u·k·|v|`: above the band
    ///   when `k ≥ REL_THRESHOLD / u`;
    /// - an instance transform perturbed by a relative e moves a hit point by about `e·|p|`: above
    ///   the band when `e ≥ REL_THRESHOLD`;
    /// - a t short by a relative e: t's interval is the same band over the incidence cosine, so
    ///   `e ≥ REL_THRESHOLD` for the hits the cameras see face-on enough;
    /// - the discrete kinds (records, mask bits, primitives) have no band: one is a fault.
    pub fn threshold(self) -> f64 {
        match self {
            Kind::VertexUlps => (REL_THRESHOLD / model::tracer::band::U32).round(),
            Kind::InstanceTransform | Kind::TBias => REL_THRESHOLD,
            Kind::SbtStride | Kind::SbtOffset | Kind::CullMask | Kind::DropPrimitive => 1.0,
        }
    }

    /// The smallest fault of the kind: whole kinds one unit, relative kinds [`REL_THRESHOLD`]. Size 0
    /// applies where this one does.
    fn smallest(self) -> f64 {
        match self.whole() {
            Some(_) => 1.0,
            None => REL_THRESHOLD,
        }
    }

    /// The sizes a detection table measures by default: below, near and above the threshold.
    pub fn default_sizes(self) -> &'static [f64] {
        match self {
            Kind::VertexUlps => &[256.0, 4096.0, 65536.0, 1048576.0],
            Kind::InstanceTransform => &[1e-5, 1e-4, 1e-3, 1e-2],
            Kind::TBias => &[1e-5, 1e-4, 1e-3, 1e-2],
            Kind::SbtStride | Kind::SbtOffset | Kind::CullMask | Kind::DropPrimitive => &[1.0],
        }
    }
}

/// How far from the geometry the rendered scenes' rays start, over the magnitude of the vertices
/// (see [`Kind::threshold`]).
pub const DISTANCE_RATIO: f64 = 40.0;

/// The terms of the band that each move a hit by up to `128u` of its distance (three vertices, the
/// origin, the direction, the instance inverse, with room to spare; see [`Kind::threshold`]).
pub const BAND_TERMS: f64 = 8.0;

/// The relative size of a fault the reference tracer's band always absorbs in the rendered scenes.
pub const REL_THRESHOLD: f64 = model::tracer::band::BAND_SAFETY_FACTOR
    * model::tracer::band::ETA_TEST
    * BAND_TERMS
    * DISTANCE_RATIO;

impl fmt::Display for Kind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One injection: a kind and its size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Injection {
    pub kind: Kind,
    pub size: f64,
}

impl Injection {
    /// Parses `KIND:SIZE` (`vertex-ulps:16`, `t-bias:1e-4`), with a message that says what is wrong.
    pub fn parse(text: &str) -> Result<Injection, String> {
        let known = || {
            Kind::ALL
                .iter()
                .map(|k| format!("{k} ({})", k.unit()))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let Some((name, size)) = text.split_once(':') else {
            return Err(format!("`{text}` is not KIND:SIZE (kinds: {})", known()));
        };
        let kind = Kind::parse(name.trim())
            .ok_or_else(|| format!("unknown injection kind `{name}` (kinds: {})", known()))?;
        let size = Injection::parse_size(kind, size.trim())?;
        Ok(Injection { kind, size })
    }

    /// Parses a size of `kind`: a whole number up to the kind's largest for the discrete kinds, a
    /// finite number in [0, 1] for the relative ones.
    pub fn parse_size(kind: Kind, text: &str) -> Result<f64, String> {
        match kind.whole() {
            Some(max) => match text.parse::<u64>() {
                Ok(n) if n <= max => Ok(n as f64),
                Ok(n) => Err(format!(
                    "{kind} size {n} is larger than {max} {}",
                    kind.unit()
                )),
                Err(_) => Err(format!(
                    "{kind} size `{text}` is not a whole number of {}",
                    kind.unit()
                )),
            },
            None => match text.parse::<f64>() {
                Ok(e) if e.is_finite() && (0.0..=1.0).contains(&e) => Ok(e),
                _ => Err(format!(
                    "{kind} size `{text}` is not a relative size between 0 and 1"
                )),
            },
        }
    }
}

impl fmt::Display for Injection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.kind, self.size)
    }
}

/// The copy a driver is handed, and what was changed.
#[derive(Debug, Clone, PartialEq)]
pub struct Injected {
    pub case: Case,
    /// Where and how the copy differs (case-file paths), for the report.
    pub what: String,
}

/// Why an injection has nothing to act on in a case.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NotApplicable(pub String);

impl fmt::Display for NotApplicable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

fn na<T>(why: impl Into<String>) -> Result<T, NotApplicable> {
    Err(NotApplicable(why.into()))
}

/// The perturbed copy of a valid trace case (see the module documentation); deterministic in
/// `(case, injection, seed)`.
pub fn inject(
    case: &Case,
    injection: &Injection,
    profile: &DeviceProfile,
    seed: u64,
) -> Result<Injected, NotApplicable> {
    if case.intent != Intent::Valid {
        return na("not a valid case");
    }
    let Some(t) = case.as_trace() else {
        return na("not a trace case");
    };
    if !t.world.launch.traces() {
        return na("the launch traces no ray");
    }
    let mut rng = SceneRng(seed ^ fnv(&case.name) ^ (injection.kind as u64).wrapping_mul(0x9E37));
    let mut out = case.clone();
    let body = out.as_trace_mut().expect("a trace case");
    let (world, call) = (&mut body.world, &mut body.call);
    // Size 0 is the case itself, for the cases where the kind's smallest fault would apply.
    let size = if injection.size == 0.0 {
        injection.kind.smallest()
    } else {
        injection.size
    };
    let what = match injection.kind {
        Kind::VertexUlps => vertex_ulps(world, call, size as u32, &mut rng)?,
        Kind::InstanceTransform => instance_transform(world, call, size, &mut rng)?,
        Kind::SbtStride => sbt_move(world, call, profile, size as u64, true, &mut rng)?,
        Kind::SbtOffset => sbt_move(world, call, profile, size as u64, false, &mut rng)?,
        Kind::CullMask => cull_mask(world, call, size as u32, &mut rng)?,
        Kind::DropPrimitive => drop_primitives(world, call, size as usize, &mut rng)?,
        Kind::TBias => t_bias(world, call, size)?,
    };
    // A copy whose every ray the model expects to end as the original's is an equivalent mutant.
    let copy = out.as_trace().expect("a trace case");
    let expected = |w: &World, c: &Call| model::semantics::expected_launch(w, c).map(|e| e.allowed);
    if expected(&copy.world, &copy.call) == expected(&t.world, &t.call) {
        return na("equivalent: the model expects the same outcomes of the copy");
    }
    if injection.size == 0.0 {
        return Ok(Injected {
            case: case.clone(),
            what: format!("size 0: the case itself (the kind applies: {what})"),
        });
    }
    Ok(Injected { case: out, what })
}

/// FNV-1a of a name: the case's part of every draw.
fn fnv(s: &str) -> u64 {
    s.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
    })
}

/// The primitives some traced ray must hit where its record shows the hit (no miss allowed, and a
/// closest-hit shader runs for each of its committable candidates), sorted, and for each traced ray
/// the t of its nearest committable hit when it is such a ray.
struct Witnesses {
    primitives: Vec<PrimitiveRef>,
    /// The exact barycentrics (b, c) of one hit each primitive must take, where it is a triangle.
    barycentrics: Vec<Option<[f64; 2]>>,
    /// `t[k]` for traced ray k.
    t: Vec<Option<f64>>,
    /// Shader binding table records whose handle some ray's record shows: the hit record of a ray
    /// that must commit one primitive (a closest-hit shader running), the miss record of a ray that
    /// must miss.
    observed: std::collections::BTreeSet<(Table, u64)>,
}

fn witnesses(world: &World, call: &Call) -> Result<Witnesses, NotApplicable> {
    let Some(expected) = model::semantics::expected_launch(world, call) else {
        return na("the model has no expected output for the launch");
    };
    let mut set = std::collections::BTreeMap::new();
    let mut t = Vec::with_capacity(expected.allowed.len());
    let mut observed = std::collections::BTreeSet::new();
    for (a, ray) in expected.allowed.iter().zip(&expected.rays) {
        if a.miss.required {
            observed.insert((Table::Miss, model::semantics::miss_record(ray.miss_index)));
        }
        // Only a hit the record shows: a closest-hit shader runs for every hit the ray may commit.
        let shown = !a.skip_closest_hit
            && a.committable.iter().all(|&i| {
                let s = &a.candidates[i].shaders;
                s.closest_hit && !s.zero_group
            });
        if a.miss.allowed || a.committable.is_empty() || !shown {
            t.push(None);
            continue;
        }
        let mut nearest = f64::INFINITY;
        for &i in &a.committable {
            for r in &a.candidates[i].reports {
                nearest = nearest.min(r.t_exact);
            }
        }
        // A primitive the ray must commit alone: a fault of it shows in the record (with two it may
        // commit, as on a shared edge, the other may stand in).
        if let [i] = a.committable[..] {
            let c = &a.candidates[i];
            let bary = c.reports.iter().find_map(|r| r.barycentrics_exact);
            set.entry((
                c.primitive.instance,
                c.primitive.geometry,
                c.primitive.primitive,
            ))
            .or_insert(bary);
            if let Some(inst) = world
                .launch
                .scene
                .instances
                .get(c.primitive.instance as usize)
            {
                observed.insert((
                    Table::Hit,
                    model::semantics::hit_record(
                        inst.sbt_record_offset,
                        c.primitive.geometry,
                        ray.sbt_offset,
                        ray.sbt_stride,
                    ),
                ));
            }
        }
        t.push(nearest.is_finite().then_some(nearest));
    }
    Ok(Witnesses {
        primitives: set
            .keys()
            .map(|&(instance, geometry, primitive)| PrimitiveRef {
                instance,
                geometry,
                primitive,
            })
            .collect(),
        barycentrics: set.values().copied().collect(),
        t,
        observed,
    })
}

fn pick<'a, T>(items: &'a [T], rng: &mut SceneRng) -> &'a T {
    &items[rng.below(items.len() as u64) as usize]
}

/// `x` moved `k` representable f32 values up or down (nextafter k times), None past the finite range.
pub fn step_ulps(x: f32, k: u32, up: bool) -> Option<f32> {
    // The f32 values in order as integers: negatives below zero, both zeros at 0.
    let ordered = |v: f32| -> i64 {
        let b = v.to_bits();
        if b >> 31 == 1 {
            -((b & 0x7FFF_FFFF) as i64)
        } else {
            b as i64
        }
    };
    let n = ordered(x) + if up { k as i64 } else { -(k as i64) };
    let y = if n < 0 {
        f32::from_bits((-n) as u32 | 0x8000_0000)
    } else {
        f32::from_bits(n as u32)
    };
    (y.is_finite() && n.unsigned_abs() <= 0x7F80_0000).then_some(y)
}

fn vertex_ulps(
    world: &mut World,
    call: &Call,
    k: u32,
    rng: &mut SceneRng,
) -> Result<String, NotApplicable> {
    let w = witnesses(world, call)?;
    let scene = &world.launch.scene;
    let triangles: Vec<(&PrimitiveRef, Option<[f64; 2]>)> = w
        .primitives
        .iter()
        .zip(w.barycentrics.iter().copied())
        .filter(|(p, _)| {
            bottom_of(scene, p).is_some_and(|b| {
                matches!(
                    scene.bottom_levels[b].geometries[p.geometry as usize].data,
                    GeometryData::Triangles(_)
                )
            })
        })
        .collect();
    if triangles.is_empty() {
        return na("no ray must hit a triangle where its record shows the hit");
    }
    let (p, bary) = *pick(&triangles, rng);
    let p = *p;
    let b = bottom_of(scene, &p).expect("a witness has a bottom level");
    // The corner nearest the hit the ray must take (the largest weight): the move shows there.
    let corner = match bary {
        Some([bb, cc]) => [1.0 - bb - cc, bb, cc]
            .iter()
            .enumerate()
            .max_by(|x, y| x.1.total_cmp(y.1))
            .map_or(0, |(k, _)| k),
        None => rng.below(3) as usize,
    };
    let up = rng.below(2) == 0;
    let GeometryData::Triangles(tri) =
        &mut world.launch.scene.bottom_levels[b].geometries[p.geometry as usize].data
    else {
        unreachable!("filtered to triangles")
    };
    let v = tri.vertex_indices(p.primitive as usize)[corner];
    let pos = tri.positions[v];
    // The largest axis: the coarsest ULP of the vertex, never a zero coordinate's denormals.
    let axis = (0..3)
        .max_by(|&a, &c| pos[a].abs().total_cmp(&pos[c].abs()))
        .unwrap_or(0);
    if pos[axis] == 0.0 {
        return na("the vertex is the origin: it has no ULP to move by");
    }
    let Some(moved) = step_ulps(pos[axis], k, up) else {
        return na("the move leaves the finite f32 range");
    };
    tri.positions[v][axis] = moved;
    Ok(format!(
        "world.launch.scene.bottom_levels[{b}].geometries[{}].data.positions[{v}][{axis}] (of instance {} primitive {}): {} -> {moved} ({}{k} ULPs)",
        p.geometry,
        p.instance,
        p.primitive,
        pos[axis],
        if up { "+" } else { "-" }
    ))
}

fn bottom_of(scene: &model::scene::Scene, p: &PrimitiveRef) -> Option<usize> {
    scene
        .instances
        .get(p.instance as usize)?
        .bottom_level
        .map(|b| b as usize)
}

fn instance_transform(
    world: &mut World,
    call: &Call,
    e: f64,
    rng: &mut SceneRng,
) -> Result<String, NotApplicable> {
    let w = witnesses(world, call)?;
    let mut hit: Vec<u32> = w.primitives.iter().map(|p| p.instance).collect();
    hit.dedup();
    if hit.is_empty() {
        return na("no ray must hit an instance where its record shows the hit");
    }
    let i = *pick(&hit, rng) as usize;
    let m = &mut world.launch.scene.instances[i].transform;
    let scale =
        m.0.iter()
            .flat_map(|r| r[..3].iter())
            .fold(0.0f32, |a, x| a.max(x.abs())) as f64;
    for row in m.0.iter_mut() {
        for x in row.iter_mut() {
            let sign = if rng.below(2) == 0 { 1.0 } else { -1.0 };
            *x = (*x as f64 + sign * e * (x.abs() as f64).max(scale)) as f32;
        }
    }
    Ok(format!(
        "world.launch.scene.instances[{i}].transform: every entry moved by {e} of max(|entry|, {scale})"
    ))
}

fn region_mut(call: &mut Call, table: Table) -> Option<&mut StridedRegion> {
    let regions = match call {
        Call::TraceRays(c) => [&mut c.raygen, &mut c.miss, &mut c.hit, &mut c.callable],
        Call::TraceRaysIndirect(c) => [&mut c.raygen, &mut c.miss, &mut c.hit, &mut c.callable],
        Call::TraceRaysNv(_) => return None,
    };
    regions.into_iter().nth(table as usize)
}

/// The handle at `offset` of `buffer` as the device reads it: unwritten memory is zero (the harness
/// zero-fills every buffer before its writes).
fn handle_read(world: &World, buffer: &str, offset: u64) -> HandleRef {
    world.handle_at(buffer, offset).unwrap_or(HandleRef::Zero)
}

fn sbt_move(
    world: &mut World,
    call: &mut Call,
    profile: &DeviceProfile,
    k: u64,
    stride: bool,
    rng: &mut SceneRng,
) -> Result<String, NotApplicable> {
    if matches!(call, Call::TraceRaysNv(_)) {
        return na("vkCmdTraceRaysNV tables are not injected");
    }
    let handle = model::semantics::handle_size(profile);
    let reads: Vec<(Table, u64)> = witnesses(world, call)?.observed.into_iter().collect();
    let tables: Vec<Table> = [Table::Hit, Table::Miss]
        .into_iter()
        .filter(|&t| reads.iter().any(|&(rt, i)| rt == t && (!stride || i >= 1)))
        .collect();
    if tables.is_empty() {
        return na(if stride {
            "no ray's record shows a hit or miss record past the first"
        } else {
            "no ray's record shows a hit or miss record"
        });
    }
    let table = *pick(&tables, rng);
    let indices: Vec<u64> = reads
        .iter()
        .filter(|&&(t, _)| t == table)
        .map(|&(_, i)| i)
        .collect();
    let old = call.region(table).expect("a KHR call").clone();
    let Some((buffer, base)) = old.address.buffer() else {
        return na("the region's address is raw");
    };
    let buffer = buffer.to_string();
    let (new_base, new_stride, new_size) = if stride {
        let s = old.stride + k * handle;
        if profile
            .limit("maxShaderGroupStride")
            .is_some_and(|max| s > max)
        {
            return na(format!(
                "a stride of {s} is past the profile's maxShaderGroupStride"
            ));
        }
        let records = if old.stride == 0 {
            1
        } else {
            old.size.div_ceil(old.stride)
        };
        (base, s, (s * records).max(old.size))
    } else {
        let align = profile
            .limit("shaderGroupBaseAlignment")
            .unwrap_or(handle)
            .max(1);
        (
            base + (k * handle).div_ceil(align) * align,
            old.stride,
            old.size,
        )
    };
    let differs = indices.iter().any(|&i| {
        handle_read(world, &buffer, base + old.stride * i)
            != handle_read(world, &buffer, new_base + new_stride * i)
    });
    if k > 0 && !differs {
        return na(format!(
            "equivalent: the {table:?} records the moved region reads hold the same handles"
        ));
    }
    let end = new_base + new_size;
    let b = world
        .buffers
        .iter_mut()
        .find(|b| b.name == buffer)
        .ok_or_else(|| NotApplicable(format!("no buffer `{buffer}`")))?;
    let grown = if end > b.size {
        let was = b.size;
        b.size = end;
        format!("; buffer `{buffer}` grown from {was} to {end} bytes (zeros)")
    } else {
        String::new()
    };
    let r = region_mut(call, table).expect("a KHR call");
    r.address = model::call::Address::InBuffer {
        buffer: buffer.clone(),
        offset: new_base,
    };
    r.stride = new_stride;
    r.size = new_size;
    let name = format!("{table:?}").to_lowercase();
    Ok(if stride {
        format!(
            "call.{name}.stride: {} -> {new_stride}, size {} -> {new_size}{grown}",
            old.stride, old.size
        )
    } else {
        format!("call.{name}.address.offset: {base} -> {new_base}{grown}")
    })
}

fn cull_mask(
    world: &mut World,
    call: &Call,
    k: u32,
    rng: &mut SceneRng,
) -> Result<String, NotApplicable> {
    let w = witnesses(world, call)?;
    let mut seen: Vec<u32> = w.primitives.iter().map(|p| p.instance).collect();
    seen.dedup();
    let launch = &world.launch;
    let rays = model::semantics::traced_rays(world, call);
    let mut masks: Vec<u32> = rays.iter().map(|r| r.cull_mask).collect();
    masks.sort();
    masks.dedup();
    let instances: Vec<u8> = launch
        .scene
        .instances
        .iter()
        .filter(|i| i.bottom_level.is_some())
        .map(|i| i.mask)
        .collect();
    if instances.is_empty() || masks.is_empty() {
        return na("no active instance");
    }
    let changes = |flip: u32| {
        masks.iter().any(|&m| {
            instances
                .iter()
                .any(|&im| (im as u32 & m & 0xFF != 0) != (im as u32 & (m ^ flip) & 0xFF != 0))
        })
    };
    // Whether flipping a bit hides an instance some ray must hit.
    let hides = |b: u32| {
        masks.iter().any(|&m| {
            seen.iter().any(|&i| {
                let im = launch.scene.instances[i as usize].mask as u32;
                im & m & 0xFF != 0 && im & (m ^ (1 << b)) & 0xFF == 0
            })
        })
    };
    // The bits that hide a hit instance, then those that change which instances some ray sees,
    // each in a drawn order, then the others.
    let mut hiding: Vec<u32> = (0..8).filter(|&b| hides(b)).collect();
    let mut relevant: Vec<u32> = (0..8).filter(|&b| !hides(b) && changes(1 << b)).collect();
    let mut other: Vec<u32> = (0..8).filter(|&b| !changes(1 << b)).collect();
    if hiding.is_empty() {
        return na(
            "no cull mask bit hides an instance a ray must hit where its record shows the hit",
        );
    }
    shuffle(&mut hiding, rng);
    shuffle(&mut relevant, rng);
    shuffle(&mut other, rng);
    let flip = hiding
        .iter()
        .chain(relevant.iter())
        .chain(other.iter())
        .take(k as usize)
        .fold(0u32, |f, b| f | 1 << b);
    if k > 0 && !changes(flip) {
        return na(format!(
            "equivalent: flipping bits {flip:#04x} sees the same instances"
        ));
    }
    let launch = &mut world.launch;
    for r in launch.rays.iter_mut() {
        r.cull_mask ^= flip;
    }
    if let Some(c) = launch.camera.as_mut() {
        c.cull_mask ^= flip;
    }
    Ok(format!("every ray's cull_mask ^= {flip:#04x}"))
}

fn shuffle<T>(v: &mut [T], rng: &mut SceneRng) {
    for i in (1..v.len()).rev() {
        let j = rng.below(i as u64 + 1) as usize;
        v.swap(i, j);
    }
}

fn drop_primitives(
    world: &mut World,
    call: &Call,
    k: usize,
    rng: &mut SceneRng,
) -> Result<String, NotApplicable> {
    let w = witnesses(world, call)?;
    let scene = &world.launch.scene;
    // (bottom level, geometry, primitive): several instances of one bottom level name it once.
    let mut hit: Vec<(usize, usize, usize)> = w
        .primitives
        .iter()
        .filter_map(|p| {
            Some((
                bottom_of(scene, p)?,
                p.geometry as usize,
                p.primitive as usize,
            ))
        })
        .collect();
    hit.sort();
    hit.dedup();
    if hit.is_empty() {
        return na("no ray must hit a primitive where its record shows the hit");
    }
    shuffle(&mut hit, rng);
    if hit.len() < k {
        return na(format!(
            "only {} primitives must be hit, fewer than {k}",
            hit.len()
        ));
    }
    let mut dropped = Vec::new();
    for &(b, g, p) in hit.iter().take(k) {
        match &mut world.launch.scene.bottom_levels[b].geometries[g].data {
            GeometryData::Triangles(t) => {
                match &mut t.indices {
                    Some(Indices::U16(ix)) => {
                        let a = ix[3 * p];
                        ix[3 * p + 1] = a;
                        ix[3 * p + 2] = a;
                    }
                    Some(Indices::U32(ix)) => {
                        let a = ix[3 * p];
                        ix[3 * p + 1] = a;
                        ix[3 * p + 2] = a;
                    }
                    None => {
                        let a = t.positions[3 * p];
                        t.positions[3 * p + 1] = a;
                        t.positions[3 * p + 2] = a;
                    }
                }
                dropped.push(format!(
                    "bottom_levels[{b}].geometries[{g}] triangle {p} degenerate"
                ));
            }
            GeometryData::Aabbs(a) => {
                a.boxes[p].min[0] = f32::NAN;
                dropped.push(format!(
                    "bottom_levels[{b}].geometries[{g}] box {p} inactive"
                ));
            }
        }
    }
    Ok(format!("world.launch.scene: {}", dropped.join(", ")))
}

fn t_bias(world: &mut World, call: &Call, e: f64) -> Result<String, NotApplicable> {
    let w = witnesses(world, call)?;
    let shifted = w.t.iter().filter(|t| t.is_some()).count();
    if shifted == 0 {
        return na("no ray must hit where its record shows the hit");
    }
    let launch = &mut world.launch;
    let mut rays: Vec<Ray> = launch.ray_list();
    for (ray, t) in rays.iter_mut().zip(&w.t) {
        if let Some(t) = t {
            let d = e * t;
            for k in 0..3 {
                ray.origin[k] = (ray.origin[k] as f64 + d * ray.direction[k] as f64) as f32;
            }
        }
    }
    let camera = launch.camera.take().is_some();
    launch.rays = rays;
    Ok(format!(
        "{shifted} rays' origins moved {e}·t along their directions{}",
        if camera {
            " (the camera's rays written out as explicit rays, in the same order)"
        } else {
            ""
        }
    ))
}

/// What a run with `--inject` did with one case (its report's `injection`).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct CaseInjection {
    /// `KIND:SIZE`.
    pub injection: String,
    /// Whether the driver ran the perturbed copy (false: not applicable, the case ran as it is).
    pub applied: bool,
    /// What the copy changed, or why the injection was not applicable.
    pub detail: String,
}

/// `summary.json`'s `inject`: the cases of a run with `--inject`.
#[derive(Debug, Default, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct InjectTotals {
    pub injection: String,
    /// Cases whose perturbed copy ran.
    pub applied: usize,
    /// Cases the injection had nothing to act on (run as they are; neither detected nor missed).
    pub not_applicable: usize,
    /// Applied cases whose outcome catches the fault ([`detects`]).
    pub detected: usize,
}

/// Whether a case's outcome catches an injected fault: the run fails it (a REQ violation or an error
/// outside its bound, or the driver crashing or hanging on the copy).
pub fn detects(outcome: crate::compare::Outcome) -> bool {
    use crate::compare::Outcome;
    matches!(outcome, Outcome::Fail | Outcome::Crash | Outcome::Timeout)
}

/// The perturbed copy of `case`, if the gate lets it reach a driver: a copy the model judges invalid
/// or not runnable is not applicable (the layer stays quiet; only the output decides).
pub fn applied(
    injection: &Injection,
    seed: u64,
    case: &Case,
    judging: &crate::run::Judging,
) -> Result<Injected, NotApplicable> {
    let injected = inject(case, injection, judging.profile, seed)?;
    if let Some(report) = crate::gate::gate(&injected.case, judging) {
        return na(format!(
            "the perturbed copy may not reach a driver: {}",
            report.detail
        ));
    }
    Ok(injected)
}

/// The case a run hands the driver in place of `case`, and what its report will say: the case itself
/// without an injection or where the injection is not applicable.
pub(crate) fn executed(
    injection: Option<&(Injection, u64)>,
    case: &Case,
    judging: &crate::run::Judging,
) -> (Case, Option<CaseInjection>) {
    let Some((injection, seed)) = injection else {
        return (case.clone(), None);
    };
    let (run, applied, detail) = match applied(injection, *seed, case, judging) {
        Ok(i) => (i.case, true, i.what),
        Err(why) => (case.clone(), false, format!("not applicable: {why}")),
    };
    (
        run,
        Some(CaseInjection {
            injection: injection.to_string(),
            applied,
            detail,
        }),
    )
}

/// The injection totals of a run's results.
pub(crate) fn totals(
    injection: &Injection,
    results: &std::path::Path,
) -> Result<InjectTotals, crate::SessionError> {
    let mut t = InjectTotals {
        injection: injection.to_string(),
        ..Default::default()
    };
    for line in crate::results::read_lines(results)? {
        match &line.report.injection {
            Some(i) if i.applied => {
                t.applied += 1;
                if detects(line.report.outcome) {
                    t.detected += 1;
                }
            }
            _ => t.not_applicable += 1,
        }
    }
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::scene::Scene;

    fn rendered(n: usize) -> (Vec<Case>, DeviceProfile) {
        let set = crate::sources::load_sources(&[]).expect("the installed registry");
        let rules = model::RuleSet::from_vuids(&set);
        let profile = crate::sources::profile_for("lavapipe").expect("profiles/lavapipe.json");
        let spec = generator::CaseSpec::rendered(model::CommandId::TraceRays);
        let cases = generator::generate(&profile, "lavapipe", &rules, &spec, n, 1).unwrap();
        (cases, profile)
    }

    fn world(c: &mut Case) -> &mut World {
        &mut c.as_trace_mut().unwrap().world
    }

    fn scene(c: &Case) -> &Scene {
        &c.as_trace().unwrap().world.launch.scene
    }

    /// The injected copies of every case the kind applies to (at least one).
    fn copies(kind: Kind, size: f64) -> Vec<(Case, Case)> {
        let (cases, profile) = rendered(12);
        let out: Vec<(Case, Case)> = cases
            .iter()
            .filter_map(|c| {
                let i = inject(c, &Injection { kind, size }, &profile, 7).ok()?;
                // Deterministic in (case, injection, seed).
                let again = inject(c, &Injection { kind, size }, &profile, 7).unwrap();
                assert_eq!(i, again);
                Some((c.clone(), i.case))
            })
            .collect();
        assert!(!out.is_empty(), "{kind} applies to none of 12 cases");
        out
    }

    #[test]
    fn size_zero_is_the_case_itself() {
        let (cases, profile) = rendered(12);
        for kind in Kind::ALL {
            let mut applied = 0;
            for c in &cases {
                if let Ok(i) = inject(c, &Injection { kind, size: 0.0 }, &profile, 7) {
                    assert_eq!(&i.case, c, "{kind}");
                    applied += 1;
                }
            }
            assert!(applied > 0, "{kind} size 0 applies to no case");
        }
    }

    #[test]
    fn a_vertex_moves_by_exactly_k_ulps_and_nothing_else_changes() {
        for (original, mut copy) in copies(Kind::VertexUlps, 4096.0) {
            let mut moved = vec![];
            for (b, (x, y)) in scene(&original)
                .bottom_levels
                .iter()
                .zip(&scene(&copy).bottom_levels)
                .enumerate()
            {
                for (g, (gx, gy)) in x.geometries.iter().zip(&y.geometries).enumerate() {
                    if let (GeometryData::Triangles(tx), GeometryData::Triangles(ty)) =
                        (&gx.data, &gy.data)
                    {
                        for (v, (px, py)) in tx.positions.iter().zip(&ty.positions).enumerate() {
                            for a in 0..3 {
                                if px[a].to_bits() != py[a].to_bits() {
                                    moved.push((b, g, v, a, px[a], py[a]));
                                }
                            }
                        }
                    }
                }
            }
            assert_eq!(moved.len(), 1, "{}: {moved:?}", original.name);
            let (b, g, v, a, was, now) = moved[0];
            let up = step_ulps(was, 4096, true) == Some(now);
            let down = step_ulps(was, 4096, false) == Some(now);
            assert!(up || down, "{was} -> {now} is not 4096 ULPs");
            let GeometryData::Triangles(t) =
                &mut world(&mut copy).launch.scene.bottom_levels[b].geometries[g].data
            else {
                unreachable!()
            };
            t.positions[v][a] = was;
            assert_eq!(copy, original);
        }
    }

    #[test]
    fn an_instance_transform_is_the_only_change() {
        for (original, mut copy) in copies(Kind::InstanceTransform, 1e-2) {
            let changed: Vec<usize> = (0..scene(&original).instances.len())
                .filter(|&i| {
                    scene(&original).instances[i].transform != scene(&copy).instances[i].transform
                })
                .collect();
            assert_eq!(changed.len(), 1, "{}", original.name);
            let i = changed[0];
            let (m0, m1) = (
                scene(&original).instances[i].transform.0,
                scene(&copy).instances[i].transform.0,
            );
            // Every entry moves by about 1% of max(|entry|, the linear part's largest).
            let scale = m0
                .iter()
                .flat_map(|r| &r[..3])
                .fold(0f32, |a, x| a.max(x.abs()));
            for r in 0..3 {
                for c in 0..4 {
                    let d = (m1[r][c] - m0[r][c]).abs() / m0[r][c].abs().max(scale);
                    assert!(
                        (d - 1e-2).abs() < 1e-4,
                        "{}: entry {r},{c} moved {d}",
                        original.name
                    );
                }
            }
            world(&mut copy).launch.scene.instances[i].transform =
                scene(&original).instances[i].transform;
            assert_eq!(copy, original);
        }
    }

    fn restore_region(original: &Case, copy: &mut Case) -> Vec<String> {
        let mut changed = vec![];
        let (o, c) = (
            original.as_trace().unwrap().clone(),
            copy.as_trace_mut().unwrap(),
        );
        for t in Table::ALL {
            if o.call.region(t) != c.call.region(t) {
                changed.push(format!("{t:?}"));
                *region_mut(&mut c.call, t).unwrap() = o.call.region(t).unwrap().clone();
            }
        }
        for (bo, bc) in o.world.buffers.iter().zip(c.world.buffers.iter_mut()) {
            // A buffer only grows, with zeros (no content is written past its old end).
            assert!(bc.size >= bo.size);
            assert_eq!(bc.contents, bo.contents);
            bc.size = bo.size;
        }
        changed
    }

    #[test]
    fn sbt_kinds_move_one_region_by_whole_handles() {
        let (_, profile) = rendered(0);
        let handle = model::semantics::handle_size(&profile);
        for (original, mut copy) in copies(Kind::SbtStride, 2.0) {
            let (o, c) = (original.as_trace().unwrap(), copy.as_trace().unwrap());
            let t = Table::ALL
                .into_iter()
                .find(|&t| o.call.region(t) != c.call.region(t))
                .expect("a region changed");
            let (ro, rc) = (o.call.region(t).unwrap(), c.call.region(t).unwrap());
            assert_eq!(rc.stride, ro.stride + 2 * handle, "{}", original.name);
            assert_eq!(rc.address, ro.address);
            assert_eq!(restore_region(&original, &mut copy).len(), 1);
            assert_eq!(copy, original);
        }
        for (original, mut copy) in copies(Kind::SbtOffset, 1.0) {
            let (o, c) = (original.as_trace().unwrap(), copy.as_trace().unwrap());
            let t = Table::ALL
                .into_iter()
                .find(|&t| o.call.region(t) != c.call.region(t))
                .expect("a region changed");
            let (ro, rc) = (o.call.region(t).unwrap(), c.call.region(t).unwrap());
            assert!(t != Table::Raygen, "raygen is never moved");
            let moved = rc.address.alignment_value() - ro.address.alignment_value();
            assert!(moved >= handle, "{moved}");
            let align = profile.limit("shaderGroupBaseAlignment").unwrap();
            assert_eq!(moved % align, 0);
            assert_eq!((rc.stride, rc.size), (ro.stride, ro.size));
            assert_eq!(restore_region(&original, &mut copy).len(), 1);
            assert_eq!(copy, original);
        }
    }

    #[test]
    fn cull_mask_flips_k_bits_of_every_ray() {
        for (original, mut copy) in copies(Kind::CullMask, 2.0) {
            let rays_o = original.as_trace().unwrap().world.launch.ray_list();
            let rays_c = copy.as_trace().unwrap().world.launch.ray_list();
            let flip = rays_o[0].cull_mask ^ rays_c[0].cull_mask;
            assert_eq!(flip.count_ones(), 2, "{}", original.name);
            assert!(flip <= 0xFF);
            let launch = &mut world(&mut copy).launch;
            for r in launch.rays.iter_mut() {
                r.cull_mask ^= flip;
            }
            if let Some(c) = launch.camera.as_mut() {
                c.cull_mask ^= flip;
            }
            assert_eq!(copy, original);
        }
    }

    #[test]
    fn dropped_primitives_keep_their_ids_and_nothing_else_changes() {
        for (original, mut copy) in copies(Kind::DropPrimitive, 1.0) {
            let (so, sc) = (scene(&original).clone(), scene(&copy).clone());
            let mut dropped = 0;
            for (b, (x, y)) in so.bottom_levels.iter().zip(&sc.bottom_levels).enumerate() {
                for (g, (gx, gy)) in x.geometries.iter().zip(&y.geometries).enumerate() {
                    match (&gx.data, &gy.data) {
                        (GeometryData::Triangles(tx), GeometryData::Triangles(ty)) => {
                            assert_eq!(tx.primitive_count(), ty.primitive_count());
                            for p in 0..tx.primitive_count() {
                                if tx.vertices(p) != ty.vertices(p) {
                                    let v = ty.vertices(p);
                                    assert!(v[0] == v[1] && v[1] == v[2], "degenerate");
                                    dropped += 1;
                                }
                            }
                        }
                        (GeometryData::Aabbs(ax), GeometryData::Aabbs(ay)) => {
                            for (bx, by) in ax.boxes.iter().zip(&ay.boxes) {
                                if bx.min[0].to_bits() != by.min[0].to_bits() {
                                    assert!(by.is_inactive() && bx.max == by.max);
                                    dropped += 1;
                                }
                            }
                        }
                        _ => panic!("geometry kinds changed"),
                    }
                    world(&mut copy).launch.scene.bottom_levels[b].geometries[g] = gx.clone();
                }
            }
            assert_eq!(dropped, 1, "{}", original.name);
            assert_eq!(copy, original);
        }
    }

    #[test]
    fn t_bias_moves_origins_along_their_directions_only() {
        for (original, mut copy) in copies(Kind::TBias, 1e-2) {
            let rays_o = original.as_trace().unwrap().world.launch.ray_list();
            let launch = &copy.as_trace().unwrap().world.launch;
            assert!(launch.camera.is_none());
            assert_eq!(launch.rays.len(), rays_o.len());
            let mut moved = 0;
            for (a, b) in rays_o.iter().zip(&launch.rays) {
                assert_eq!(
                    (a.direction, a.tmin, a.tmax, a.flags, a.cull_mask),
                    (b.direction, b.tmin, b.tmax, b.flags, b.cull_mask)
                );
                if a.origin != b.origin {
                    moved += 1;
                    // origin' − origin is parallel to the direction, forward.
                    let d = [0, 1, 2].map(|k| (b.origin[k] - a.origin[k]) as f64);
                    let s = [0, 1, 2]
                        .map(|k| d[k] * a.direction[k] as f64)
                        .iter()
                        .sum::<f64>();
                    let dd = a.direction.map(|x| x as f64);
                    let cross = [
                        d[1] * dd[2] - d[2] * dd[1],
                        d[2] * dd[0] - d[0] * dd[2],
                        d[0] * dd[1] - d[1] * dd[0],
                    ];
                    let n = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                    assert!(s > 0.0 && n(cross) <= 1e-3 * n(d) * n(dd) + 1e-6);
                }
            }
            assert!(moved > 0);
            let w = world(&mut copy);
            w.launch.rays = original.as_trace().unwrap().world.launch.rays.clone();
            w.launch.camera = original.as_trace().unwrap().world.launch.camera.clone();
            assert_eq!(copy, original);
        }
    }

    #[test]
    fn step_ulps_is_nextafter_k_times() {
        assert_eq!(
            step_ulps(1.0, 1, true),
            Some(f32::from_bits(1.0f32.to_bits() + 1))
        );
        assert_eq!(
            step_ulps(1.0, 1, false),
            Some(f32::from_bits(1.0f32.to_bits() - 1))
        );
        let tiny = f32::from_bits(1);
        assert_eq!(step_ulps(tiny, 2, false), Some(-tiny));
        assert_eq!(
            step_ulps(-1.5, 3, true),
            Some(-f32::from_bits(1.5f32.to_bits() - 3))
        );
        assert_eq!(step_ulps(f32::MAX, 1, true), None);
        assert_eq!(step_ulps(2.0, 0, true), Some(2.0));
    }

    #[test]
    fn parsing_says_what_is_wrong() {
        let i = Injection::parse("vertex-ulps:16").unwrap();
        assert_eq!((i.kind, i.size), (Kind::VertexUlps, 16.0));
        assert_eq!(i.to_string(), "vertex-ulps:16");
        assert_eq!(Injection::parse("t-bias:1e-4").unwrap().size, 1e-4);
        for (text, says) in [
            ("t-bias", "not KIND:SIZE"),
            ("nope:1", "unknown injection kind `nope`"),
            ("sbt-offset:65", "larger than 64 handles"),
            ("drop-primitive:x", "not a whole number of primitives"),
            ("t-bias:inf", "between 0 and 1"),
            ("t-bias:-0.1", "between 0 and 1"),
        ] {
            let e = Injection::parse(text).unwrap_err();
            assert!(e.contains(says), "{text}: {e}");
        }
    }

    #[test]
    fn only_valid_trace_cases_with_rays_are_injected() {
        let (cases, profile) = rendered(1);
        let mut invalid = cases[0].clone();
        invalid.intent = Intent::Violates {
            vuid: "VUID-x".into(),
            also: vec![],
        };
        let i = Injection {
            kind: Kind::CullMask,
            size: 1.0,
        };
        assert!(inject(&invalid, &i, &profile, 1)
            .unwrap_err()
            .0
            .contains("not a valid case"));
        let mut dark = cases[0].clone();
        let launch = &mut world(&mut dark).launch;
        launch.rays.clear();
        launch.camera = None;
        assert!(inject(&dark, &i, &profile, 1)
            .unwrap_err()
            .0
            .contains("traces no ray"));
    }
}
