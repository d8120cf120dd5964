//! What a launch shows of its faults, from the model's expected outcomes: the primitives a ray must
//! commit alone with a closest-hit shader running, the t of each such ray's hit, and the shader
//! binding table records whose handle a ray's record names.

use super::{na, NotApplicable};
use model::call::{Call, Table};
use model::tracer::PrimitiveRef;
use model::world::World;

/// The primitives some traced ray must hit where its record shows the hit (no miss allowed, and a
/// closest-hit shader runs for each of its committable candidates), sorted, and for each traced ray
/// the t of its nearest committable hit when it is such a ray.
pub(super) struct Witnesses {
    pub(super) primitives: Vec<PrimitiveRef>,
    /// The exact barycentrics (b, c) of one hit each primitive must take, where it is a triangle.
    pub(super) barycentrics: Vec<Option<[f64; 2]>>,
    /// `t[k]` for traced ray k.
    pub(super) t: Vec<Option<f64>>,
    /// Shader binding table records whose handle some ray's record shows: the hit record of a ray
    /// that must commit one primitive (a closest-hit shader running), the miss record of a ray that
    /// must miss.
    pub(super) observed: std::collections::BTreeSet<(Table, u64)>,
}

pub(super) fn witnesses(world: &World, call: &Call) -> Result<Witnesses, NotApplicable> {
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
