//! A valid launch's expected output: each distinct ray of the launch traced once, the distinct
//! rays shared out over the calling thread and the process's helper threads, each resolving the
//! launch's hit records through a memo.

use super::*;

/// The hit groups of the hit records a launch's rays reached, by record index, and the last hit
/// and miss records resolved (a launch's rays mostly reach the same few): a record's group depends
/// on the world and call alone, so the rays of one launch share the memo.
#[derive(Default)]
pub(super) struct HitRecordMemo {
    hits: std::cell::RefCell<HashMap<u64, HitShaders, BuildHasherDefault<RecordHasher>>>,
    last_hit: std::cell::Cell<Option<(u64, HitShaders)>>,
    last_miss: std::cell::Cell<Option<(u64, MissShader)>>,
}

/// [`allowed_for_ray_with`], the hit records resolved through `memo`.
pub(super) fn allowed_for_ray_memo(
    world: &World,
    call: &Call,
    prepared: &PreparedScene,
    ray: &Ray,
    config: &TracerConfig,
    stats: &mut TracerStats,
    memo: &HitRecordMemo,
) -> Option<AllowedOutcomes> {
    let mut answer = None;
    allowed_for_rays_memo(
        world,
        call,
        prepared,
        &[ray],
        config,
        stats,
        memo,
        |_, a| answer = a,
    );
    answer
}

/// [`allowed_for_ray_memo`] of each ray, traced together ([`crate::tracer::trace_rays`]): `answer`
/// gets each ray's index and outcomes (None: undefined), as each ray finishes.
#[allow(clippy::too_many_arguments)] // the one-ray form's arguments, and where the answers go
pub(super) fn allowed_for_rays_memo(
    world: &World,
    call: &Call,
    prepared: &PreparedScene,
    rays: &[&Ray],
    config: &TracerConfig,
    stats: &mut TracerStats,
    memo: &HitRecordMemo,
    mut answer: impl FnMut(usize, Option<AllowedOutcomes>),
) {
    let scene = &world.launch.scene;
    let hit_for = |ray: &Ray| {
        let (sbt_offset, sbt_stride) = (ray.sbt_offset, ray.sbt_stride);
        move |i: u32, g: u32| {
            let inst = &scene.instances[i as usize];
            let record = hit_record(inst.sbt_record_offset, g, sbt_offset, sbt_stride);
            if let Some((r, h)) = memo.last_hit.get() {
                if r == record {
                    return h;
                }
            }
            let known = memo.hits.borrow().get(&record).copied();
            let h = known.unwrap_or_else(|| {
                let h = hit_shaders(world, call, record);
                memo.hits.borrow_mut().insert(record, h);
                h
            });
            memo.last_hit.set(Some((record, h)));
            h
        }
    };
    let miss_for = |ray: &Ray| {
        let record = miss_record(ray.miss_index);
        match memo.last_miss.get() {
            Some((r, m)) if r == record => m,
            _ => {
                let m = miss_shader(world, call, record);
                memo.last_miss.set(Some((record, m)));
                m
            }
        }
    };
    // Mostly every ray of a launch has the same shader binding table offsets and miss index: then
    // one table serves all, without a table and a hit-group lookup made per ray.
    let key = |r: &Ray| (r.sbt_offset, r.sbt_stride, r.miss_index);
    let (shared_hit, hits, tables, shared);
    let pairs: Vec<(&Ray, &ShaderTable)> = match rays.split_first() {
        Some((&first, rest)) if rest.iter().all(|r| key(r) == key(first)) => {
            shared_hit = hit_for(first);
            shared = ShaderTable {
                hit: &shared_hit,
                miss: miss_for(first),
            };
            rays.iter().map(|&r| (r, &shared)).collect()
        }
        _ => {
            hits = rays.iter().map(|r| hit_for(r)).collect::<Vec<_>>();
            tables = rays
                .iter()
                .zip(&hits)
                .map(|(r, hit)| ShaderTable {
                    hit,
                    miss: miss_for(r),
                })
                .collect::<Vec<_>>();
            rays.iter().copied().zip(&tables).collect()
        }
    };
    trace_rays(prepared, &pairs, config, stats, |k, a| answer(k, a.ok()));
}

/// What a valid launch may write: its dimensions, and for each traced ray (launch ID `i` traces ray
/// `i % rays.len()`) the outcomes the spec allows. No rays: every launch ID writes the
/// [`crate::tracer::record::RayRecord::no_shader`] record.
#[derive(Debug, Clone)]
pub struct ExpectedLaunch {
    pub dimensions: [u32; 3],
    pub rays: Vec<Ray>,
    /// `allowed[k]` for `rays[k]`, held once per distinct ray.
    pub allowed: PerRay<AllowedOutcomes>,
    /// The tracer's counters for the launch's distinct rays (memoised per distinct ray).
    pub stats: TracerStats,
}

impl ExpectedLaunch {
    /// The ray index launch ID `id` traces, None when the launch traces no ray.
    pub fn ray_of(&self, id: usize) -> Option<usize> {
        (!self.rays.is_empty()).then(|| id % self.rays.len())
    }

    /// The number of launch IDs (saturating at u64::MAX): the model holds one outcome set per ray,
    /// never one per launch ID (an indirect command may state 2^96 invocations).
    pub fn invocations(&self) -> u64 {
        self.dimensions
            .iter()
            .map(|&d| d as u64)
            .fold(1, u64::saturating_mul)
    }
}

/// One value per ray of a launch, held once per distinct ray: a launch of many copies of one ray (an
/// explicit ray list repeated, a ray through a closed fan's vertex in every launch ID) keeps one set
/// of outcomes, not one per copy, so its memory follows its distinct rays, not its launch size. The
/// values are held in chunks as the threads that traced them made them (no copy into one buffer on
/// the launch's serial path).
#[derive(Clone)]
pub struct PerRay<T> {
    /// The values of the distinct rays, in order of first appearance: value `d` is
    /// `chunks[d >> shift][d & mask]`, every chunk but the last holding `1 << shift` values.
    chunks: Vec<Vec<T>>,
    shift: u32,
    /// The number of values held.
    distinct_len: usize,
    /// For each ray its distinct one's index; empty where every ray is distinct (ray `k`'s value is
    /// then the `k`th).
    of: Vec<u32>,
}

impl<T> Default for PerRay<T> {
    fn default() -> PerRay<T> {
        PerRay::new(Vec::new(), Vec::new())
    }
}

impl<T> PerRay<T> {
    /// The values of the distinct rays, and for each ray the index of its distinct one.
    pub fn new(distinct: Vec<T>, of: Vec<u32>) -> PerRay<T> {
        PerRay::from_chunks(vec![distinct], usize::BITS - 1, of)
    }

    /// [`PerRay::new`] with the values in chunks of `1 << shift` (the last may hold fewer).
    fn from_chunks(chunks: Vec<Vec<T>>, shift: u32, of: Vec<u32>) -> PerRay<T> {
        let distinct_len = chunks.iter().map(Vec::len).sum();
        debug_assert!(chunks
            .iter()
            .rev()
            .skip(1)
            .all(|c| c.len() == 1usize << shift));
        debug_assert!(of.iter().all(|&d| (d as usize) < distinct_len));
        let identity = of.len() == distinct_len;
        PerRay {
            chunks,
            shift,
            distinct_len,
            of: if identity { Vec::new() } else { of },
        }
    }

    /// The number of rays.
    pub fn len(&self) -> usize {
        if self.of.is_empty() {
            self.distinct_len
        } else {
            self.of.len()
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The value of each ray, in ray order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = &T> + '_ {
        (0..self.len()).map(move |k| &self[k])
    }

    /// The number of values held: one per distinct ray.
    pub fn distinct_len(&self) -> usize {
        self.distinct_len
    }
}

impl<T> std::ops::Index<usize> for PerRay<T> {
    type Output = T;
    fn index(&self, k: usize) -> &T {
        let d = if self.of.is_empty() {
            k
        } else {
            self.of[k] as usize
        };
        &self.chunks[d >> self.shift][d & ((1usize << self.shift) - 1)]
    }
}

/// The distinct values as one list and the rays' indices into it, however the values are held.
impl<T: std::fmt::Debug> std::fmt::Debug for PerRay<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        struct Values<'a, T>(&'a [Vec<T>]);
        impl<T: std::fmt::Debug> std::fmt::Debug for Values<'_, T> {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.debug_list().entries(self.0.iter().flatten()).finish()
            }
        }
        f.debug_struct("PerRay")
            .field("distinct", &Values(&self.chunks))
            .field("of", &self.of)
            .finish()
    }
}

/// Equal where every ray has an equal value, however the values are held.
impl<T: PartialEq> PartialEq for PerRay<T> {
    fn eq(&self, other: &PerRay<T>) -> bool {
        self.len() == other.len() && self.iter().eq(other.iter())
    }
}

/// The expected output of a valid call, or None when the dimensions are not known or the scene is
/// undefined. Each distinct ray is traced once; large launches are traced on every core the
/// machine offers (each ray's outcomes depend on nothing else, and the counters are sums, so the
/// answer is the same however the rays are shared out).
pub fn expected_launch(world: &World, call: &Call) -> Option<ExpectedLaunch> {
    let dims = call.dimensions(world)?;
    let rays = traced_rays(world, call);
    let mut stats = TracerStats::default();
    let mut allowed = PerRay::default();
    if !rays.is_empty() {
        let (traced, shift, of) = if workers_for(rays.len()) > 1 {
            traced_beside_distinct(world, call, &rays, &mut stats)?
        } else {
            // The first launch ray of each distinct ray, and for every ray the distinct one it is.
            let prepared = prepared(&world.launch.scene)?;
            let (distinct, of) = distinct_rays(&rays);
            let (traced, shift) =
                trace_distinct(world, call, &prepared, &rays, &distinct, &mut stats)?;
            (traced, shift, of)
        };
        allowed = PerRay::from_chunks(traced, shift, of);
    }
    Some(ExpectedLaunch {
        dimensions: dims,
        rays,
        allowed,
        stats,
    })
}

/// The first launch ray of each distinct ray, and for every ray the distinct one it is.
type DistinctRays = (Vec<u32>, Vec<u32>);

/// A launch's outcomes in chunks, the chunks' shift (see [`PerRay::from_chunks`]) and for every ray its
/// distinct one.
type Traced = (Vec<Vec<AllowedOutcomes>>, u32, Vec<u32>);

/// The outcomes of a launch of rays enough for more than one thread, in one call of the helpers (None:
/// the scene or a ray is undefined). Waking a sleeping helper takes tens of microseconds, about as
/// long as finding a few thousand rays' distinct ones, so the helper is woken first: the first run
/// (the caller's, mostly) finds the distinct rays and lays out the chunks, the other looks the
/// prepared scene up meanwhile (its memo compares the scene's data in full) and then traces the last
/// chunks in launch order, a guess at the layout that holds whenever the rays are all distinct (see
/// [`guess_last_chunks`]); each goes on to trace chunks as soon as the layout is there (a helper that
/// starts late finds its part done).
fn traced_beside_distinct(
    world: &World,
    call: &Call,
    rays: &[Ray],
    stats: &mut TracerStats,
) -> Option<Traced> {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::OnceLock;
    /// What the first run lays out for all.
    struct Layout {
        prepared: Arc<PreparedScene>,
        distinct: Vec<u32>,
        of: Vec<u32>,
        sharing: Sharing,
    }
    /// Sets the cell to None unless it is set: a run that unwinds before giving its part leaves
    /// the others a value to stop on, not a wait without end (`run_beside` resumes its panic).
    struct NoneUnlessSet<'a, T>(&'a OnceLock<Option<T>>);
    impl<T> Drop for NoneUnlessSet<'_, T> {
        fn drop(&mut self) {
            let _ = self.0.set(None);
        }
    }
    let runs = workers_for(rays.len());
    let layout: OnceLock<Option<Layout>> = OnceLock::new();
    // The prepared scene: Some(None) where it is undefined, None where its run unwound.
    let scene: OnceLock<Option<Option<Arc<PreparedScene>>>> = OnceLock::new();
    let (scene_taken, layout_taken) = (AtomicBool::new(false), AtomicBool::new(false));
    let look_up_scene = || {
        if !scene_taken.swap(true, Ordering::AcqRel) {
            let _unset = NoneUnlessSet(&scene);
            let _ = scene.set(Some(prepared(&world.launch.scene)));
        }
    };
    let work = || {
        if !layout_taken.swap(true, Ordering::AcqRel) {
            let _unset = NoneUnlessSet(&layout);
            let (distinct, of) = distinct_rays(rays);
            look_up_scene();
            let found = match wait_for(&scene) {
                Some(Some(prepared)) => Some(Layout {
                    prepared: prepared.clone(),
                    sharing: Sharing::new(distinct.len(), workers_for(distinct.len()).min(runs)),
                    distinct,
                    of,
                }),
                _ => None,
            };
            let _ = layout.set(found);
        } else {
            look_up_scene();
            // Rays are mostly all distinct, when the layout is the launch's own order: while the
            // first run still lays it out, the others trace its last chunks in that order, kept
            // only if the layout turns out to be it.
            if let Some(Some(prepared)) = wait_for(&scene) {
                let guessed =
                    guess_last_chunks(rays.len(), &layout, |ids, stats, memo, undefined| {
                        trace_ids(world, call, prepared, rays, ids, stats, memo, undefined)
                    });
                if let Some(l) = wait_for(&layout) {
                    if l.distinct.len() == rays.len() {
                        l.sharing.claim(guessed);
                    }
                }
            }
        }
        if let Some(l) = wait_for(&layout) {
            l.sharing.work(&l.distinct, |ids, stats, memo, undefined| {
                trace_ids(world, call, &l.prepared, rays, ids, stats, memo, undefined)
            });
        }
    };
    crate::helpers::run_beside(runs - 1, &work);
    let Layout { sharing, of, .. } = layout.into_inner().flatten()?;
    let (traced, shift) = sharing.finish(stats)?;
    Some((traced, shift, of))
}

/// How a run traces one chunk of a launch: the chunk's ray indices, the run's counters, its hit-record
/// memo and the flag an undefined ray sets; the chunk's outcomes, or None where a ray is undefined.
trait TraceChunk:
    Fn(
    &[u32],
    &mut TracerStats,
    &HitRecordMemo,
    &std::sync::atomic::AtomicBool,
) -> Option<Vec<AllowedOutcomes>>
{
}

impl<F> TraceChunk for F where
    F: Fn(
        &[u32],
        &mut TracerStats,
        &HitRecordMemo,
        &std::sync::atomic::AtomicBool,
    ) -> Option<Vec<AllowedOutcomes>>
{
}

/// Chunks of a launch of `rays` rays traced in launch order from the last one back, each begun only
/// while `layout` is unset: the chunks (of [`Sharing::CHUNK`] rays), each with its outcomes and the
/// counters of its tracing. A chunk with an undefined ray ends the guessing (the layout's tracing
/// finds that ray again).
fn guess_last_chunks<L>(
    rays: usize,
    layout: &std::sync::OnceLock<L>,
    trace: impl TraceChunk,
) -> Guessed {
    let mut guessed = Vec::new();
    let memo = HitRecordMemo::default();
    let undefined = std::sync::atomic::AtomicBool::new(false);
    let mut ids = Vec::with_capacity(Sharing::CHUNK);
    for chunk in (0..rays.div_ceil(Sharing::CHUNK)).rev() {
        if layout.get().is_some() {
            break;
        }
        ids.clear();
        ids.extend(
            (chunk * Sharing::CHUNK..((chunk + 1) * Sharing::CHUNK).min(rays)).map(|i| i as u32),
        );
        let mut stats = TracerStats::default();
        match trace(&ids, &mut stats, &memo, &undefined) {
            Some(outcomes) => guessed.push((chunk, outcomes, stats)),
            None => break,
        }
    }
    guessed
}

/// Chunks traced in launch order before the layout was known ([`guess_last_chunks`]): each chunk's
/// number, outcomes and counters.
type Guessed = Vec<(usize, Vec<AllowedOutcomes>, TracerStats)>;

/// The value of a cell another run of the same call sets (or sets to None as it unwinds): waited
/// for awake, as it mostly comes within microseconds, then in naps of 50 µs.
fn wait_for<T>(cell: &std::sync::OnceLock<T>) -> &T {
    let mut spins = 0u32;
    loop {
        if let Some(v) = cell.get() {
            return v;
        }
        spins = spins.saturating_add(1);
        if spins < 1 << 16 {
            std::hint::spin_loop();
        } else {
            // Long (a large scene prepared for the first time): the core is given up meanwhile.
            std::thread::park_timeout(std::time::Duration::from_micros(50));
        }
    }
}

/// The index of the first of each distinct ray of `rays`, and for every ray the position of its
/// distinct one in that list. The table is an open-addressed one of 8-byte slots (a hash tag and a
/// distinct ray's number) at most half full, the thread's, kept between launches: for a launch of
/// thousands of rays it stays in the cache, where a map holding the 52-byte keys would not, and a
/// tag that matches is confirmed by comparing the two rays' keys in full.
pub(super) fn distinct_rays(rays: &[Ray]) -> DistinctRays {
    distinct_rays_hashed(rays, ray_key_hash)
}

/// A hash of a [`ray_key`]: its words in pairs, three independent folded multiplies and one to
/// join them (a short dependency chain; a launch hashes every ray before the first is traced).
/// Deterministic; keys are still compared in full, so a collision costs time, never an answer.
fn ray_key_hash(key: &[u32; 13]) -> u64 {
    let pair = |i: usize| key[i] as u64 | (key[i + 1] as u64) << 32;
    let fold = |a: u64, b: u64| {
        let p = a as u128 * b as u128;
        p as u64 ^ (p >> 64) as u64
    };
    let a = fold(
        pair(0) ^ 0x243F_6A88_85A3_08D3,
        pair(2) ^ 0x1319_8A2E_0370_7344,
    );
    let b = fold(
        pair(4) ^ 0xA409_3822_299F_31D0,
        pair(6) ^ 0x082E_FA98_EC4E_6C89,
    );
    let c = fold(
        pair(8) ^ 0x4528_21E6_38D0_1377,
        pair(10) ^ 0xBE54_66CF_34E9_0C6C,
    );
    fold(
        a ^ c ^ 0xC0AC_29B7_C97C_50DD,
        b ^ key[12] as u64 ^ 0x3F84_D5B5_B547_0917,
    )
}

/// [`distinct_rays`] with the keys hashed by `hash` (a test's hash that sends every key to one slot
/// with one tag: the probing and the comparison of keys decide everything).
fn distinct_rays_hashed(rays: &[Ray], hash: impl Fn(&[u32; 13]) -> u64) -> DistinctRays {
    thread_local! {
        static TABLE: std::cell::RefCell<Vec<(u32, u32)>> = const { std::cell::RefCell::new(Vec::new()) };
    }
    TABLE.with(|table| {
        let mut table = table.borrow_mut();
        let size = (2 * rays.len()).next_power_of_two().max(16);
        let mask = size - 1;
        table.clear();
        table.resize(size, (0, 0));
        // Room for every ray to be distinct, as they mostly are: growing by doubling would copy
        // and touch fresh memory a dozen times on the launch's serial path.
        let mut distinct: Vec<u32> = Vec::with_capacity(rays.len());
        let mut of = Vec::with_capacity(rays.len());
        for (i, ray) in rays.iter().enumerate() {
            let key = ray_key(ray);
            let h = hash(&key);
            let tag = (h >> 32) as u32;
            let mut at = h as usize & mask;
            // A slot's second field is the distinct ray's number plus one; 0 is an empty slot.
            let d = loop {
                match table[at] {
                    (_, 0) => {
                        distinct.push(i as u32);
                        table[at] = (tag, distinct.len() as u32);
                        break distinct.len() as u32 - 1;
                    }
                    (t, n)
                        if t == tag && ray_key(&rays[distinct[n as usize - 1] as usize]) == key =>
                    {
                        break n - 1;
                    }
                    _ => at = (at + 1) & mask,
                }
            };
            of.push(d);
        }
        // A launch far larger than the usual leaves no table of its size behind.
        if table.capacity() > 1 << 17 {
            *table = Vec::new();
        }
        (distinct, of)
    })
}

/// Distinct rays per worker below which a launch is traced on one thread (a thread costs about
/// as much as tracing a few dozen rays).
const RAYS_PER_WORKER: usize = 256;

/// How many threads trace a launch of `distinct` distinct rays: every core the process may use, one per
/// [`RAYS_PER_WORKER`] rays at most.
fn workers_for(distinct: usize) -> usize {
    crate::helpers::cores()
        .min(distinct / RAYS_PER_WORKER)
        .max(1)
}

/// The outcomes of `rays[distinct[k]]` for each k, or None when one is undefined, traced on the
/// calling thread alone (a launch for several threads is shared out by [`traced_beside_distinct`]);
/// the counters summed into `stats`. The outcomes come as one chunk, with a shift no index reaches
/// (see [`PerRay::from_chunks`]).
fn trace_distinct(
    world: &World,
    call: &Call,
    prepared: &PreparedScene,
    rays: &[Ray],
    distinct: &[u32],
    stats: &mut TracerStats,
) -> Option<(Vec<Vec<AllowedOutcomes>>, u32)> {
    let undefined = std::sync::atomic::AtomicBool::new(false);
    let memo = HitRecordMemo::default();
    let all = trace_ids(
        world, call, prepared, rays, distinct, stats, &memo, &undefined,
    )?;
    Some((vec![all], usize::BITS - 1))
}

/// The outcomes of the distinct rays `ids` (indices into `rays`), traced together, in their order;
/// None when one is undefined (`undefined` is then set, and the others may be missing).
#[allow(clippy::too_many_arguments)] // the launch, its rays, and what the worker keeps
fn trace_ids(
    world: &World,
    call: &Call,
    prepared: &PreparedScene,
    rays: &[Ray],
    ids: &[u32],
    stats: &mut TracerStats,
    memo: &HitRecordMemo,
    undefined: &std::sync::atomic::AtomicBool,
) -> Option<Vec<AllowedOutcomes>> {
    let traced: Vec<&Ray> = ids.iter().map(|&i| &rays[i as usize]).collect();
    // Answers come as rays finish, each to its place.
    let mut out: Vec<Option<AllowedOutcomes>> = Vec::new();
    out.resize_with(ids.len(), || None);
    allowed_for_rays_memo(
        world,
        call,
        prepared,
        &traced,
        &TracerConfig::default(),
        stats,
        memo,
        |k, a| {
            if a.is_none() {
                undefined.store(true, std::sync::atomic::Ordering::Relaxed);
            }
            out[k] = a;
        },
    );
    // Collected in place, without a second buffer.
    out.into_iter().collect()
}

/// The distinct rays of a launch shared out over its workers: in chunks, the chunks in one
/// contiguous segment per worker. A worker traces its own segment from the front (neighbouring rays
/// meet the same nodes and items, in its own core's cache — and launch after launch of one scene, the
/// same ones), then takes chunks from the back of the others', so an expensive part of the image does
/// not leave one worker behind. Each puts its chunk's outcomes in the chunk's place. A chunk's rays
/// are walked together, twelve at a time, and the last few of each walk alone: chunks of 64 rather
/// than 32 traced the instanced copies' launch 2-3 % faster in `render_rays` (eight alternations),
/// 128 no faster again and the grid's slower (a late chunk leaves one worker behind).
struct Sharing {
    /// Each chunk's outcomes, set once by the worker that traced it.
    done: Vec<std::sync::OnceLock<Vec<AllowedOutcomes>>>,
    /// Each worker's chunks not yet taken.
    segments: Vec<Mutex<std::collections::VecDeque<usize>>>,
    /// The order the runs start in (the calling thread's, which starts at once, is usually first).
    started: std::sync::atomic::AtomicUsize,
    /// Each run's counters, summed by [`Sharing::finish`].
    parts: Mutex<Vec<TracerStats>>,
    /// A ray was undefined.
    undefined: std::sync::atomic::AtomicBool,
}

impl Sharing {
    const SHIFT: u32 = 6;
    const CHUNK: usize = 1 << Self::SHIFT;

    /// `distinct` rays in chunks, in `workers` segments.
    fn new(distinct: usize, workers: usize) -> Sharing {
        let chunks = distinct.div_ceil(Self::CHUNK);
        let per_worker = chunks.div_ceil(workers).max(1);
        Sharing {
            done: (0..chunks).map(|_| std::sync::OnceLock::new()).collect(),
            segments: (0..workers)
                .map(|w| Mutex::new((w * per_worker..((w + 1) * per_worker).min(chunks)).collect()))
                .collect(),
            started: std::sync::atomic::AtomicUsize::new(0),
            parts: Mutex::new(Vec::new()),
            undefined: std::sync::atomic::AtomicBool::new(false),
        }
    }

    /// One worker's run: chunks of `distinct` traced by `trace` until none is left (or a ray was
    /// undefined).
    fn work(&self, distinct: &[u32], trace: impl TraceChunk) {
        let workers = self.segments.len();
        let lock = |k: usize| self.segments[k].lock().unwrap_or_else(|e| e.into_inner());
        let mut stats = TracerStats::default();
        let memo = HitRecordMemo::default();
        let home = self
            .started
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed)
            % workers;
        loop {
            // One segment locked at a time (the home guard is gone before another is taken).
            let own = lock(home).pop_front();
            let next =
                own.or_else(|| (1..workers).find_map(|k| lock((home + k) % workers).pop_back()));
            let Some(chunk) = next else { break };
            if self.undefined.load(std::sync::atomic::Ordering::Relaxed) {
                break;
            }
            let ids =
                &distinct[chunk * Self::CHUNK..((chunk + 1) * Self::CHUNK).min(distinct.len())];
            if let Some(outcomes) = trace(ids, &mut stats, &memo, &self.undefined) {
                // Each chunk is taken from its segment once.
                let _ = self.done[chunk].set(outcomes);
            }
        }
        self.parts
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(stats);
    }

    /// Chunks traced before the layout was known, for a layout of the launch's own order: each one
    /// not yet taken is taken from its segment and done, its counters kept; one already taken is
    /// left to its taker, so each ray is counted once.
    fn claim(&self, guessed: Guessed) {
        let mut kept = TracerStats::default();
        for (chunk, outcomes, stats) in guessed {
            let taken = self.segments.iter().any(|segment| {
                let mut segment = segment.lock().unwrap_or_else(|e| e.into_inner());
                match segment.iter().position(|&c| c == chunk) {
                    Some(at) => {
                        segment.remove(at);
                        true
                    }
                    None => false,
                }
            });
            if taken {
                let _ = self.done[chunk].set(outcomes);
                kept.merge(&stats);
            }
        }
        self.parts
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(kept);
    }

    /// The chunks' outcomes and their shift, the runs' counters summed into `stats`; None where a ray
    /// was undefined.
    fn finish(self, stats: &mut TracerStats) -> Option<(Vec<Vec<AllowedOutcomes>>, u32)> {
        for part in self
            .parts
            .into_inner()
            .unwrap_or_else(|e| e.into_inner())
            .iter()
        {
            stats.merge(part);
        }
        if self.undefined.into_inner() {
            return None;
        }
        // Every chunk was traced (no ray was undefined).
        let chunks = self
            .done
            .into_iter()
            .map(|c| c.into_inner())
            .collect::<Option<Vec<_>>>()?;
        Some((chunks, Self::SHIFT))
    }
}

/// A hasher for the hit record memo's record indices: a multiply-rotate mix of the words,
/// deterministic (the map compares keys in full, so a collision costs time, never an answer).
#[derive(Default)]
struct RecordHasher(u64);

impl std::hash::Hasher for RecordHasher {
    fn finish(&self) -> u64 {
        let h = self.0;
        (h ^ (h >> 29)).wrapping_mul(0xBF58_476D_1CE4_E5B9) ^ (h >> 32)
    }
    fn write(&mut self, bytes: &[u8]) {
        let mut words = bytes.chunks_exact(4);
        for w in &mut words {
            self.write_u32(u32::from_le_bytes([w[0], w[1], w[2], w[3]]));
        }
        for b in words.remainder() {
            self.write_u32(*b as u32);
        }
    }
    fn write_u32(&mut self, x: u32) {
        self.0 = (self.0.rotate_left(5) ^ x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
    fn write_usize(&mut self, x: usize) {
        self.write_u32(x as u32);
        self.write_u32((x as u64 >> 32) as u32);
    }
}

#[cfg(test)]
mod distinct_ray_tests {
    use super::*;

    /// The first of each distinct ray and every ray's distinct one, by comparing each ray's key with
    /// that of every distinct ray found before it.
    fn by_comparison(rays: &[Ray]) -> (Vec<u32>, Vec<u32>) {
        let mut distinct: Vec<u32> = Vec::new();
        let of = rays
            .iter()
            .enumerate()
            .map(|(i, r)| {
                match distinct
                    .iter()
                    .position(|&d| ray_key(&rays[d as usize]) == ray_key(r))
                {
                    Some(k) => k as u32,
                    None => {
                        distinct.push(i as u32);
                        distinct.len() as u32 - 1
                    }
                }
            })
            .collect();
        (distinct, of)
    }

    /// Rays drawn with repeats from a few dozen, some a bit apart from another (tmax one ULP
    /// higher, −0 for +0, another miss index): the table finds the same distinct rays as comparing
    /// them all, launch after launch of different sizes (its slots reused), also when every key
    /// hashes alike.
    #[test]
    fn the_table_of_distinct_rays_finds_what_comparing_every_pair_finds() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 33) as usize
        };
        let mut pool = Vec::new();
        for k in 0..40 {
            let base = Ray::new([0.0, k as f32, 1.0], [0.0, 0.0, -1.0], 0.0, 10.0);
            pool.push(base);
            pool.push(Ray {
                tmax: f32::from_bits(10.0f32.to_bits() + 1),
                ..base
            });
            pool.push(Ray {
                miss_index: 1,
                ..base
            });
        }
        pool.push(Ray::new([-0.0, 0.0, 1.0], [0.0, 0.0, -1.0], 0.0, 10.0));
        for len in [3000, 7, 1, 600, 5000] {
            let rays: Vec<Ray> = (0..len).map(|_| pool[next() % pool.len()]).collect();
            let (distinct, of) = distinct_rays(&rays);
            let (expect_distinct, expect_of) = by_comparison(&rays);
            assert_eq!(distinct, expect_distinct, "launch of {len}");
            assert_eq!(of, expect_of, "launch of {len}");
            // Every key hashed alike: one chain of slots, each tag matching, the keys deciding.
            let colliding = distinct_rays_hashed(&rays, |_| 7);
            assert_eq!(colliding, (expect_distinct, expect_of), "launch of {len}");
            // The near twins stayed apart: more distinct rays than base rays were drawn.
            assert!(len < 600 || distinct.len() > 40, "launch of {len}");
        }
    }
}

#[cfg(test)]
mod shared_out_tests {
    use super::*;

    /// `test` given the hand-made case launching the 24x24 icosphere workload's scene (its world
    /// and call), the scene prepared, and the workload's rays.
    fn on_icosphere_launch(test: impl FnOnce(&World, &Call, &PreparedScene, &[Ray])) {
        let mut case = crate::test_cases::hand_case();
        let workload = crate::tracer::workload::standard_workload(24, "icosphere");
        case.as_trace_mut()
            .expect("a trace case")
            .world
            .launch
            .scene = workload.scene.clone();
        let body = case.as_trace().expect("a trace case");
        let prepared = prepared(&body.world.launch.scene).expect("a defined scene");
        test(&body.world, &body.call, &prepared, &workload.rays);
    }

    /// The outcomes and counters of `rays`, all distinct, traced on the calling thread alone.
    fn traced_on_one_thread(
        world: &World,
        call: &Call,
        prepared: &PreparedScene,
        rays: &[Ray],
    ) -> (PerRay<AllowedOutcomes>, TracerStats) {
        let distinct: Vec<u32> = (0..rays.len() as u32).collect();
        let mut stats = TracerStats::default();
        let (chunks, shift) = trace_distinct(world, call, prepared, rays, &distinct, &mut stats)
            .expect("defined rays");
        (PerRay::from_chunks(chunks, shift, Vec::new()), stats)
    }

    /// However many workers share a launch's distinct rays out (segments of one chunk or of many,
    /// more workers than chunks), every ray gets the outcomes and counters one thread gives it.
    #[test]
    fn every_worker_count_gives_the_outcomes_of_one_thread() {
        on_icosphere_launch(|world, call, prepared, rays| {
            let distinct: Vec<u32> = (0..rays.len() as u32).collect();
            let (one, one_stats) = traced_on_one_thread(world, call, prepared, rays);
            assert_eq!(one.len(), rays.len());
            assert!(
                one.iter().any(|o| !o.candidates.is_empty()),
                "some ray hits"
            );
            // 576 rays in 9 chunks: segments of 5 and 4, of 3, of 2 and 1 chunks, and workers without
            // any.
            for workers in [2, 3, 5, 18, 40] {
                let mut stats = TracerStats::default();
                let sharing = Sharing::new(distinct.len(), workers);
                crate::helpers::run_beside(workers - 1, &|| {
                    sharing.work(&distinct, |ids, stats, memo, undefined| {
                        trace_ids(world, call, prepared, rays, ids, stats, memo, undefined)
                    })
                });
                let (chunks, shift) = sharing.finish(&mut stats).expect("defined rays");
                assert!(chunks.len() > 1, "{workers} workers");
                let many = PerRay::from_chunks(chunks, shift, Vec::new());
                assert_eq!(many.len(), rays.len(), "{workers} workers");
                assert!(many == one, "{workers} workers");
                assert_eq!(stats.rays, one_stats.rays, "{workers} workers");
                assert_eq!(stats.pair_tests, one_stats.pair_tests, "{workers} workers");
            }
        });
    }

    /// Chunks guessed in launch order before the layout is known: every chunk while the layout is
    /// unset, none once it is set; claimed for the launch's own order, each chunk not yet taken is
    /// kept with its counters and one already taken stays its taker's, so every ray gets the
    /// outcomes and counters one thread gives it.
    #[test]
    fn chunks_guessed_before_the_layout_are_kept_once() {
        on_icosphere_launch(|world, call, prepared, rays| {
            let distinct: Vec<u32> = (0..rays.len() as u32).collect();
            let (one, one_stats) = traced_on_one_thread(world, call, prepared, rays);
            let trace = |ids: &[u32],
                         stats: &mut TracerStats,
                         memo: &HitRecordMemo,
                         undefined: &std::sync::atomic::AtomicBool| {
                trace_ids(world, call, prepared, rays, ids, stats, memo, undefined)
            };
            let set = std::sync::OnceLock::from(());
            assert!(guess_last_chunks(rays.len(), &set, trace).is_empty());
            let unset = std::sync::OnceLock::<()>::new();
            let guessed = guess_last_chunks(rays.len(), &unset, trace);
            let chunks = rays.len().div_ceil(Sharing::CHUNK);
            assert_eq!(
                guessed.iter().map(|g| g.0).collect::<Vec<_>>(),
                (0..chunks).rev().collect::<Vec<_>>()
            );
            // Two workers' segments; the second's last chunk already taken and traced by its taker.
            let sharing = Sharing::new(distinct.len(), 2);
            let taken = sharing.segments[1]
                .lock()
                .unwrap()
                .pop_back()
                .expect("a chunk");
            assert_eq!(taken, chunks - 1);
            let mut taker = TracerStats::default();
            let ids = &distinct[taken * Sharing::CHUNK..];
            let outcomes = trace(
                ids,
                &mut taker,
                &HitRecordMemo::default(),
                &std::sync::atomic::AtomicBool::new(false),
            )
            .expect("defined rays");
            sharing.done[taken].set(outcomes).expect("set once");
            sharing.parts.lock().unwrap().push(taker);
            sharing.claim(guessed);
            assert!(
                sharing
                    .segments
                    .iter()
                    .all(|s| s.lock().unwrap().is_empty()),
                "every chunk not taken was claimed"
            );
            let mut stats = TracerStats::default();
            let (chunks, shift) = sharing.finish(&mut stats).expect("defined rays");
            let claimed = PerRay::from_chunks(chunks, shift, Vec::new());
            assert!(claimed == one);
            assert_eq!(stats.rays, one_stats.rays);
            assert_eq!(stats.pair_tests, one_stats.pair_tests);
        });
    }

    /// The launch traced in one call of the helpers (distinct rays and scene found beside each other,
    /// then traced on every run) gives every ray the outcomes one thread gives it, with repeated rays
    /// mapped to their first; an undefined ray makes the launch undefined there too.
    #[test]
    fn tracing_beside_the_distinct_rays_gives_the_outcomes_of_one_thread() {
        on_icosphere_launch(|world, call, prepared, workload_rays| {
            // Every ray, then the first 100 again: repeated rays.
            let mut rays = workload_rays.to_vec();
            rays.extend_from_slice(&workload_rays[..100]);
            // Two runs or more wherever the machine has two cores (one run on one core is the same path).
            assert!(
                workers_for(rays.len()) > 1
                    || std::thread::available_parallelism().is_ok_and(|n| n.get() == 1),
                "{} rays",
                rays.len()
            );
            let (distinct, of) = distinct_rays(&rays);
            let mut one_stats = TracerStats::default();
            let (chunks, shift) =
                trace_distinct(world, call, prepared, &rays, &distinct, &mut one_stats)
                    .expect("defined rays");
            let one = PerRay::from_chunks(chunks, shift, of.clone());
            let mut stats = TracerStats::default();
            let (chunks, shift, beside_of) =
                traced_beside_distinct(world, call, &rays, &mut stats).expect("defined rays");
            assert_eq!(beside_of, of);
            let beside = PerRay::from_chunks(chunks, shift, beside_of);
            assert_eq!(beside.len(), rays.len());
            assert!(beside == one);
            assert_eq!(stats.rays, one_stats.rays);
            assert_eq!(stats.pair_tests, one_stats.pair_tests);
            // An undefined ray (NaN origin) makes the launch undefined.
            rays[300].origin[0] = f32::NAN;
            assert!(
                traced_beside_distinct(world, call, &rays, &mut TracerStats::default()).is_none()
            );
        });
    }
}

#[cfg(test)]
mod per_ray_tests {
    use super::*;
    use crate::test_cases::hand_case;

    /// Rays of one launch with different shader binding table offsets or miss indices (the launch's
    /// rays traced with a table each) and with the same (one table for all) get the outcomes each
    /// ray traced alone gets: a launch whose rays differ in the miss index alone, in the offset
    /// alone, or in neither.
    #[test]
    fn rays_of_other_tables_in_one_launch_get_their_own_tables() {
        let workload = crate::tracer::workload::standard_workload(64, "icosphere");
        let patterns: [fn(usize) -> (u32, u32); 3] = [
            |k| (0, (k / 5 % 2) as u32),
            |k| ((k / 7 % 2) as u32, 0),
            |_| (1, 1),
        ];
        for (n, pattern) in patterns.iter().enumerate() {
            let mut case = workload.as_launch_of(hand_case(), 64);
            let body = case.as_trace_mut().expect("a trace case");
            for (k, ray) in body.world.launch.rays.iter_mut().enumerate() {
                (ray.sbt_offset, ray.miss_index) = pattern(k);
            }
            let launch = expected_launch(&body.world, &body.call).expect("a defined launch");
            let p = prepared(&body.world.launch.scene).expect("a defined scene");
            let mut alone = TracerStats::default();
            // What each table reaches: the miss shaders, and the hit groups of rays that hit.
            let (mut misses, mut hits) = (Vec::new(), Vec::new());
            for (k, ray) in body.world.launch.rays.iter().enumerate().step_by(3) {
                let own = allowed_for_ray(&body.world, &body.call, &p, ray, &mut alone)
                    .expect("a defined ray");
                assert_eq!(launch.allowed[k], own, "pattern {n}, ray {k}");
                if !misses.contains(&own.miss_shader) {
                    misses.push(own.miss_shader);
                }
                if let Some(c) = own.candidates.first() {
                    if !hits.contains(&c.shaders) {
                        hits.push(c.shaders);
                    }
                }
            }
            // Miss indices 0 and 1 reach two miss records, offsets 0 and 1 a hit group and the
            // zero group: each pattern's rays were told apart.
            assert_eq!(
                (misses.len(), hits.len()),
                [(2, 1), (1, 2), (1, 1)][n],
                "pattern {n}"
            );
        }
    }

    /// A launch of many copies of a few rays keeps one outcome set per distinct ray, and each copy
    /// reads the set its own ray traced alone gives.
    #[test]
    fn copies_of_a_ray_share_one_outcome_set_that_is_the_rays_own() {
        let workload = crate::tracer::workload::standard_workload(64, "icosphere");
        // A 64x64 launch whose 4096 rays are copies of three of the workload's, hit and miss.
        let mut case = workload.as_launch_of(hand_case(), 64);
        let body = case.as_trace_mut().expect("a trace case");
        let few: Vec<Ray> = [0, 2080, 4095].map(|k| body.world.launch.rays[k]).to_vec();
        body.world.launch.rays = (0..4096).map(|i| few[(i * 7) % few.len()]).collect();
        let many = expected_launch(&body.world, &body.call).expect("a defined launch");
        assert_eq!(many.allowed.len(), 4096);
        assert!(
            many.allowed.iter().any(|a| !a.candidates.is_empty()),
            "some copy hits"
        );
        assert!(
            many.allowed.distinct_len() <= few.len(),
            "{} outcome sets held for {} distinct rays",
            many.allowed.distinct_len(),
            few.len()
        );
        let mut alone = TracerStats::default();
        let p = prepared(&body.world.launch.scene).expect("a defined scene");
        for (k, ray) in body.world.launch.rays.iter().enumerate().step_by(97) {
            let own = allowed_for_ray(&body.world, &body.call, &p, ray, &mut alone)
                .expect("a defined ray");
            assert_eq!(many.allowed[k], own, "ray {k}");
        }
        // Every ray distinct: the outcomes are held as they are, one per ray.
        let all = PerRay::new(vec!['a', 'b', 'c'], vec![0, 1, 2]);
        assert_eq!(all.iter().collect::<String>(), "abc");
        assert_eq!((all.len(), all.distinct_len()), (3, 3));
        let shared = PerRay::new(vec!['a', 'b'], vec![0, 1, 1, 0]);
        assert_eq!(shared.iter().collect::<String>(), "abba");
        assert_eq!((shared.len(), shared.distinct_len()), (4, 2));
        // Held in chunks of two: the same values, and equal to the same held in one.
        let chunked = PerRay::from_chunks(vec![vec!['a', 'b'], vec!['c']], 1, vec![2, 0, 1, 1]);
        assert_eq!(chunked.iter().collect::<String>(), "cabb");
        assert_eq!((chunked.len(), chunked.distinct_len()), (4, 3));
        assert!(chunked == PerRay::new(vec!['a', 'b', 'c'], vec![2, 0, 1, 1]));
        assert!(chunked != PerRay::new(vec!['a', 'b', 'c'], vec![2, 0, 1, 0]));
    }
}
