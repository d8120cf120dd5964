//! The model's expectation of ray records, as compact C tables the program judges the records it
//! reads back by (`judge_records` in `runtime.c`): per distinct ray of a valid launch (or per ray of a
//! build's traced check) what the model allows — whether it may miss and by which group, the invocation
//! count bounds, the candidates (which may be committed, with their group, custom index and each
//! hit kind's t and barycentric intervals; which run any-hit) and the watertight groups that must not
//! be hit twice — the same decisions `model::tracer::judge` makes on them.

use crate::c::Emitter;
use model::tracer::{AllowedOutcomes, Interval};

/// A C double literal (exact: Rust's shortest round-trip form, read back by the C compiler).
fn double(x: f64) -> String {
    if x == f64::INFINITY {
        "INFINITY".into()
    } else if x == f64::NEG_INFINITY {
        "-INFINITY".into()
    } else if x.is_nan() {
        "NAN".into()
    } else {
        format!("{x:?}")
    }
}

fn interval(i: &Interval) -> String {
    format!("{}, {}", double(i.lo), double(i.hi))
}

/// Whether a launch ID of this ray may end with neither a miss nor a closest-hit shader writing
/// (as `model::tracer::judge` decides it).
fn no_shader_allowed(a: &AllowedOutcomes) -> bool {
    let miss_silent = a.miss.allowed && a.miss_shader.zero_group;
    let hit_silent = a.committable.iter().any(|&i| {
        let c = &a.candidates[i];
        a.skip_closest_hit || c.shaders.zero_group || !c.shaders.closest_hit
    });
    miss_silent || hit_silent
}

/// Writes the tables (`ray_rules`, `candidates`, `reports`, `watertight`, `members`) of the rays whose
/// allowed outcomes `allowed` gives, in order, and their counts; `source` names where they come from
/// (the comment above the tables).
pub(crate) fn tables<'a>(
    e: &mut Emitter,
    allowed: impl ExactSizeIterator<Item = &'a AllowedOutcomes>,
    source: &str,
) {
    let mut rules = Vec::with_capacity(allowed.len());
    let mut candidates = Vec::new();
    let mut reports = Vec::new();
    let mut groups = Vec::new();
    let mut members = Vec::new();
    for (k, a) in allowed.enumerate() {
        let first_candidate = candidates.len();
        for (i, c) in a.candidates.iter().enumerate() {
            let first_report = reports.len();
            for r in &c.reports {
                let bary = match r.barycentrics {
                    Some([b, cc]) => format!("1, {}, {}", interval(&b), interval(&cc)),
                    None => "0, 0, 0, 0, 0".into(),
                };
                reports.push(format!(
                    "{{0x{:x}, {}, {bary}}}",
                    r.hit_kind,
                    interval(&r.t)
                ));
            }
            let runs_closest = !c.shaders.zero_group && c.shaders.closest_hit;
            candidates.push(format!(
                "{{{}, {}, {}, {}, {}, {}, {}, {}, {}, {}, {}}}",
                c.primitive.instance,
                c.primitive.geometry,
                c.primitive.primitive,
                a.committable.contains(&i) as u8,
                c.confirmation.runs_any_hit() as u8,
                c.no_duplicate_any_hit as u8,
                runs_closest as u8,
                c.shaders.group,
                c.custom_index,
                first_report,
                c.reports.len()
            ));
        }
        let first_group = groups.len();
        for g in &a.watertight {
            groups.push(format!("{{{}, {}}}", members.len(), g.members.len()));
            for m in &g.members {
                members.push(format!(
                    "{{{}, {}, {}}}",
                    m.instance, m.geometry, m.primitive
                ));
            }
        }
        let max = |m: Option<u32>| m.map_or("UNBOUNDED".to_string(), |v| v.to_string());
        rules.push(format!(
            "/* ray {k} */ {{{}, {}, {}, {}, {}, {}, {}, {}, {}, {}, {}, {}, {}, {}}}",
            a.miss.allowed as u8,
            a.miss_shader.zero_group as u8,
            a.miss_shader.group,
            no_shader_allowed(a) as u8,
            a.skip_closest_hit as u8,
            a.vary as u8,
            a.any_hit.min,
            max(a.any_hit.max),
            a.intersection.min,
            max(a.intersection.max),
            first_candidate,
            a.candidates.len(),
            first_group,
            a.watertight.len()
        ));
    }
    e.line(&format!(
        "/* What the model allows each {source}, judged as model::tracer::judge judges:"
    ));
    e.line(" * launch ID i traces ray i % ray_rule_count. */");
    let table = |e: &mut Emitter, ty: &str, name: &str, rows: &[String], empty: &str| {
        e.line(&format!(
            "static const struct {ty} {name}[{}] = {{",
            rows.len().max(1)
        ));
        if rows.is_empty() {
            e.line(&format!("    {empty},"));
        }
        for r in rows {
            e.line(&format!("    {r},"));
        }
        e.line("};");
    };
    table(e, "ray_rule", "ray_rules", &rules, "{0}");
    table(e, "candidate_rule", "candidate_rules", &candidates, "{0}");
    table(e, "report_rule", "report_rules", &reports, "{0}");
    table(e, "watertight_rule", "watertight_rules", &groups, "{0}");
    table(e, "primitive_ref", "watertight_members", &members, "{0}");
    e.line(&format!(
        "static const struct launch_rules launch_rules = {{ray_rules, {}, candidate_rules, report_rules, watertight_rules, watertight_members}};",
        rules.len()
    ));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn doubles_are_exact_c_literals() {
        assert_eq!(double(f64::INFINITY), "INFINITY");
        assert_eq!(double(f64::NEG_INFINITY), "-INFINITY");
        assert_eq!(double(0.1), "0.1");
        let x = 1.0f64 + f64::EPSILON;
        assert_eq!(double(x).parse::<f64>().unwrap(), x);
        assert_eq!(double(-2.0), "-2.0");
    }
}
