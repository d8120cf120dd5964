//! Doctored build checks fed to the session's comparison, end to end: valid build cases run on
//! lavapipe (a triangle, an AABB and an instance structure whose true records pass the reference tracer's
//! judgement), and each planted fault in the device's records — a primitive swapped for another, a
//! hit turned into a miss, t off by twice its bound — makes the case fail.

mod common;

use common::{traced, Lavapipe, DEVICE};
use harness::observe::Output;
use harness::TraceCheck;
use model::accel::check::{hits_of, BuildCheck};
use model::tracer::record::RayRecord as R;
use session::{compare, Outcome};

fn at(ray: usize, word: usize) -> usize {
    ray * R::WORDS + word
}

#[test]
fn planted_faults_in_build_records_fail() {
    let _one = DEVICE.lock().unwrap_or_else(|e| e.into_inner());
    let mut lvp = Lavapipe::new();
    let mut tried = std::collections::BTreeSet::new();
    for seed in 0..6 {
        for case in generator::accel::generate(&lvp.profile, &lvp.rules, seed, 6)
            .into_iter()
            .filter(|c| c.name.ends_with("-valid"))
        {
            let body = case.as_accel().unwrap();
            let kind = format!(
                "{:?}",
                body.call.infos[0].geometries[0].data.geometry_type()
            );
            if tried.contains(&kind) {
                continue;
            }
            let ran = lvp.run(&case, TraceCheck::Auto);
            if ran.report.outcome != Outcome::Pass {
                continue;
            }
            let t = traced(&ran);
            let check = BuildCheck::of(ran.case.as_accel().unwrap()).unwrap();
            // A ray that must hit, and another that hits a different primitive.
            let must: Vec<usize> = (0..check.rays.len())
                .filter(|&k| !check.allowed[k].miss.allowed && t.hits[k].is_some())
                .collect();
            let Some(&k) = must.first() else { continue };
            let Some(&other) = must.iter().find(|&&j| t.hits[j] != t.hits[k]) else {
                continue;
            };
            tried.insert(kind.clone());
            let obs = ran.observation.clone().unwrap();
            let judge = |w: &[u32]| {
                let mut o = obs.clone();
                let mut tb = t.clone();
                tb.records = w.to_vec();
                tb.hits = hits_of(w);
                o.output = Some(Output::Rays(tb));
                compare(&ran.case, &lvp.profile, &ran.verdict, &o, &lvp.triage, 0.0)
            };
            let truth = judge(&t.records);
            assert_eq!(
                truth.outcome,
                Outcome::Pass,
                "{}: {}",
                case.name,
                truth.detail
            );
            assert!(truth
                .rendered
                .as_ref()
                .is_some_and(|r| r.rays as usize == check.rays.len()));
            let c = &check.allowed[k].candidates[check.allowed[k].committable[0]];
            let bound = c.reports[0].t.radius();
            let t_exact = c.reports[0].t_exact;
            type Fault = Box<dyn Fn(&mut [u32])>;
            let faults: Vec<(&str, Fault)> = vec![
                (
                    "primitive swapped",
                    Box::new(move |w| {
                        for word in [
                            R::INSTANCE_ID,
                            R::CUSTOM_INDEX,
                            R::GEOMETRY_INDEX,
                            R::PRIMITIVE_ID,
                        ] {
                            w[at(k, word)] = w[at(other, word)];
                        }
                    }),
                ),
                (
                    "hit turned into a miss",
                    Box::new(move |w| {
                        w[at(k, R::OUTCOME)] = R::MISS;
                        w[at(k, R::GROUP)] = model::accel::scene::MISS_GROUP;
                    }),
                ),
                (
                    "t off by twice its bound",
                    Box::new(move |w| {
                        w[at(k, R::T)] = ((t_exact + 2.0 * bound) as f32).to_bits();
                    }),
                ),
            ];
            for (name, fault) in &faults {
                let mut w = t.records.clone();
                fault(&mut w);
                assert_ne!(w, t.records, "{name}: the fault changes the records");
                let r = judge(&w);
                assert_eq!(r.outcome, Outcome::Fail, "{kind} {name}: {}", r.detail);
                assert!(
                    r.rendered.as_ref().is_some_and(|x| x.failures >= 1),
                    "{kind} {name}"
                );
            }
        }
    }
    assert_eq!(
        tried.len(),
        3,
        "a triangle, an AABB and an instance case were doctored: {tried:?}"
    );
}
