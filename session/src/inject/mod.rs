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

mod run;
mod witness;

use witness::witnesses;

pub use run::{applied, detects, CaseInjection, InjectTotals};
pub(crate) use run::{executed, totals};

#[cfg(test)]
mod tests;
