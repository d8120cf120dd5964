//! The shader binding table records a launch reads: the raygen record, the hit records its rays'
//! candidates reach, the miss record of each ray a miss is allowed for, and the callable records —
//! from a launch traced whole where one is kept (`crate::expected`), else by tracing only until each
//! miss record is known to be read.

use super::*;

/// Every shader binding table record the launch reads, as (table, record index), sorted: the raygen
/// record, every hit record a possible candidate reaches ([`reached_hit_records`]), the miss record of
/// each ray a miss is allowed for, and the callable records executed. Empty when the launch runs no
/// invocation.
pub fn records_read(world: &World, call: &Call) -> Vec<(Table, u64)> {
    if launch_ids(world, call) == Some(0) {
        return vec![];
    }
    // The gate asks for a case's records long before the rules of its judgement do (a run gates a
    // whole chunk of cases first), and tracing a rendered launch's rays costs far more than
    // fingerprinting it; so the records are kept by the fingerprint of the world and the call (the
    // key its whole traced launch is kept by, `crate::expected`). A launch of a few rays in a few
    // primitives is found again for less than its world's fingerprint (the world's resources and
    // buffers are most of it): found each time it is asked, its misses by tracing.
    if is_small_launch(world) {
        return records_read_traced(world, call, None);
    }
    static MEMO: crate::fingerprint::Memo<Vec<(Table, u64)>, 4096> =
        crate::fingerprint::Memo::new();
    let key = crate::expected::key(world, call);
    MEMO.get_or(key, || records_read_traced(world, call, key))
}

/// The most rays and primitives of a launch [`records_read`] finds each time instead of keeping.
const SMALL_LAUNCH: usize = 64;

/// A launch without a camera whose rays and whose scene's primitives (over its bottom levels) are at
/// most [`SMALL_LAUNCH`] each, in at most [`SMALL_LAUNCH`] instances.
fn is_small_launch(world: &World) -> bool {
    let launch = &world.launch;
    let primitives: usize = launch
        .scene
        .bottom_levels
        .iter()
        .flat_map(|b| &b.geometries)
        .map(|g| match &g.data {
            crate::scene::GeometryData::Triangles(t) => t.primitive_count(),
            crate::scene::GeometryData::Aabbs(a) => a.boxes.len(),
        })
        .sum();
    launch.camera.is_none()
        && launch.rays.len() <= SMALL_LAUNCH
        && launch.scene.instances.len() <= SMALL_LAUNCH
        && primitives <= SMALL_LAUNCH
}

/// [`records_read`] computed: the hit records of the launch's reach, and a miss record for each ray a
/// miss is allowed for (from the whole traced launch kept by `key`, when one is).
fn records_read_traced(world: &World, call: &Call, key: Option<u128>) -> Vec<(Table, u64)> {
    let mut out = vec![(Table::Raygen, 0)];
    out.extend(
        reached_hit_records(world, call)
            .into_iter()
            .map(|(i, _)| (Table::Hit, i)),
    );
    let rays = traced_rays(world, call);
    if !rays.is_empty() {
        // A launch traced whole already (the gate of a valid case) knows its misses.
        let misses = match key.and_then(crate::expected::lookup) {
            Some(e) => misses_of(&e),
            None => misses_by_tracing(world, call, &rays),
        };
        out.extend(misses.into_iter().map(|m| (Table::Miss, m)));
    }
    out.extend(
        world
            .launch
            .callables
            .iter()
            .map(|&c| (Table::Callable, c as u64)),
    );
    out.sort();
    out.dedup();
    out
}

/// The miss records of the rays of a launch traced whole that a miss is allowed for, sorted.
pub(crate) fn misses_of(e: &ExpectedLaunch) -> Vec<u64> {
    let misses: BTreeSet<u64> = e
        .rays
        .iter()
        .zip(e.allowed.iter())
        .filter(|(_, a)| a.miss.allowed)
        .map(|(ray, _)| miss_record(ray.miss_index))
        .collect();
    misses.into_iter().collect()
}

/// The miss records a miss is allowed for, found by tracing only until each miss record is known to
/// be read (an undefined ray's, or any ray's of a scene the tracer refuses, counts as read), sorted.
pub(crate) fn misses_by_tracing(world: &World, call: &Call, rays: &[Ray]) -> Vec<u64> {
    let mut stats = TracerStats::default();
    let prepared = prepared(&world.launch.scene);
    let mut seen: std::collections::HashSet<[u32; 13]> = std::collections::HashSet::new();
    let mut misses_read: BTreeSet<u64> = BTreeSet::new();
    for ray in rays {
        // A miss record already read needs no other ray traced to be read (launches share a few
        // miss indices among many rays).
        let record = miss_record(ray.miss_index);
        if misses_read.contains(&record) || !seen.insert(ray_key(ray)) {
            continue;
        }
        let miss = match &prepared {
            Some(p) => {
                allowed_for_ray(world, call, p, ray, &mut stats).is_none_or(|a| a.miss.allowed)
            }
            None => true,
        };
        if miss {
            misses_read.insert(record);
        }
    }
    misses_read.into_iter().collect()
}
