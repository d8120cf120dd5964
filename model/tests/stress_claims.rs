//! Every stress family's cases assert what they claim about themselves, in exact arithmetic; the
//! claims are the ones the family is about; and a claim made false by one ULP is caught.

use model::scene::Scene;
use model::stress::{families, Claim, StressCase};
use model::tracer::PreparedScene;
use std::collections::BTreeMap;

const SEEDS: u64 = 3;

fn kinds(case: &StressCase) -> BTreeMap<&'static str, usize> {
    let mut m = BTreeMap::new();
    for c in &case.claims {
        *m.entry(c.kind()).or_default() += 1;
    }
    m
}

/// The claim kinds each family must make (at least one of each, on every case).
fn required_kinds(family: &str) -> &'static [&'static str] {
    match family {
        "watertight-edges" => &["closed-mesh", "through-shared-edge"],
        "watertight-vertices" => &["closed-mesh", "through-shared-vertex"],
        "far-from-origin" => &[
            "closed-mesh",
            "translated-copy",
            "exact-translation",
            "far-from-origin",
            "through-shared-edge",
            "through-shared-vertex",
            "through-interior",
        ],
        "extreme-scale" => &["closed-mesh", "coordinate-range", "through-shared-edge"],
        "slivers-and-tiny" => &["sliver", "tiny", "through-interior"],
        "grazing" => &["grazing", "through-interior"],
        "ray-length" => &["closed-mesh", "scaled-direction"],
        "t-window" => &["closed-mesh", "t-window"],
        "ill-conditioned" => &["closed-mesh", "conditioned"],
        "stacked-transforms" => &["closed-mesh", "stacked-transforms", "through-shared-edge"],
        "mirrored" => &["closed-mesh", "mirrored", "through-interior"],
        "large-mesh" => &["closed-mesh", "min-triangles", "through-shared-edge"],
        other => panic!("family {other} has no expectation here: add one"),
    }
}

#[test]
fn every_case_proves_its_claims_in_exact_arithmetic() {
    let mut total_claims = 0;
    for f in families() {
        for seed in 0..SEEDS {
            let case = f.case(seed, f.test_size);
            assert_eq!(case.rays.len(), f.test_size, "{}: ray count", case.name);
            assert!(
                case.scene.undefined(&case.rays).is_empty(),
                "{}: {:?}",
                case.name,
                case.scene.undefined(&case.rays)
            );
            PreparedScene::new(&case.scene).expect("defined");
            let failures = case.check_claims();
            assert!(failures.is_empty(), "{}: {:?}", case.name, failures);
            let k = kinds(&case);
            for want in required_kinds(f.name) {
                assert!(
                    k.contains_key(want),
                    "{} makes no {want} claim: {k:?}",
                    case.name
                );
            }
            total_claims += case.claims.len();
            if seed == 0 {
                eprintln!("{:<20} {:>5} rays {k:?}", f.name, case.rays.len());
            }
        }
    }
    assert!(total_claims > 1000, "{total_claims} claims");
}

#[test]
fn generation_is_deterministic() {
    for f in families() {
        let (a, b) = (f.case(7, f.test_size), f.case(7, f.test_size));
        assert_eq!(a.scene, b.scene, "{}", f.name);
        assert_eq!(a.rays, b.rays, "{}", f.name);
        assert_eq!(a.claims, b.claims, "{}", f.name);
        let c = f.case(8, f.test_size);
        assert_ne!(a.rays, c.rays, "{}: seeds must matter", f.name);
    }
}

fn next_up(x: f32) -> f32 {
    if x == 0.0 {
        f32::from_bits(1)
    } else if x > 0.0 {
        f32::from_bits(x.to_bits() + 1)
    } else {
        f32::from_bits(x.to_bits() - 1)
    }
}

/// Whether moving the ray's origin by one ULP along some axis makes the claim false (a move
/// within the plane of the ray and the edge keeps an edge claim true, so all three are tried).
fn nudge_breaks(case: &StressCase, claim: &Claim, ray: u32) -> bool {
    (0..3).any(|k| {
        let mut bad = case.clone();
        let o = &mut bad.rays[ray as usize].origin[k];
        *o = next_up(*o);
        claim.check(&bad).is_err()
    })
}

#[test]
fn a_claim_one_ulp_off_is_caught() {
    let mut caught: BTreeMap<&'static str, usize> = BTreeMap::new();
    for f in families() {
        let case = f.case(1, f.test_size);
        for (i, claim) in case.claims.iter().enumerate() {
            let mut bad = case.clone();
            match claim {
                Claim::ThroughSharedEdge { ray, .. } | Claim::ThroughSharedVertex { ray, .. } => {
                    assert!(
                        nudge_breaks(&case, claim, *ray),
                        "{}: claim {i} ({claim:?}) survives a one-ulp move of the origin",
                        case.name
                    );
                    *caught.entry(claim.kind()).or_default() += 1;
                    continue;
                }
                Claim::ScaledDirection { ray, .. } => {
                    let d = &mut bad.rays[*ray as usize].direction;
                    d[0] = next_up(d[0]);
                }
                Claim::TWindow { ray, limit, .. } => {
                    // Pull the limit onto the far side of the window: many ULPs away.
                    let r = &mut bad.rays[*ray as usize];
                    let x = match limit {
                        model::stress::TLimit::Tmin => &mut r.tmin,
                        model::stress::TLimit::Tmax => &mut r.tmax,
                    };
                    *x *= 1.001;
                }
                Claim::Mirrored { instance } => {
                    let m = &mut bad.scene.instances[*instance as usize].transform;
                    for row in m.0.iter_mut() {
                        row[0] = -row[0];
                    }
                }
                Claim::TranslatedCopy { copy, .. } => {
                    if let model::scene::GeometryData::Triangles(t) =
                        &mut bad.scene.bottom_levels[*copy as usize].geometries[0].data
                    {
                        t.positions[0][0] = next_up(t.positions[0][0]);
                    }
                }
                Claim::ClosedMesh { bottom_level, .. } => {
                    drop_last_triangle(&mut bad.scene, *bottom_level);
                }
                _ => continue,
            }
            assert!(
                claim.check(&bad).is_err(),
                "{}: claim {i} ({claim:?}) survives being made false",
                case.name
            );
            *caught.entry(claim.kind()).or_default() += 1;
        }
    }
    eprintln!("caught: {caught:?}");
    for k in [
        "through-shared-edge",
        "through-shared-vertex",
        "scaled-direction",
        "t-window",
        "mirrored",
        "translated-copy",
        "closed-mesh",
    ] {
        assert!(
            caught.get(k).copied().unwrap_or(0) > 0,
            "no {k} claim was doctored"
        );
    }
}

fn drop_last_triangle(scene: &mut Scene, bottom_level: u32) {
    if let model::scene::GeometryData::Triangles(t) =
        &mut scene.bottom_levels[bottom_level as usize].geometries[0].data
    {
        match &mut t.indices {
            Some(model::scene::Indices::U16(v)) => v.truncate(v.len() - 3),
            Some(model::scene::Indices::U32(v)) => v.truncate(v.len() - 3),
            None => t.positions.truncate(t.positions.len() - 3),
        }
    }
}

/// A fan that is closed but leaves out a triangle around its vertex (a copy of one of its own,
/// appended to the geometry) is refused — by a fresh proof, and through an index of the triangles
/// around each vertex that was built on the intact scene before.
#[test]
fn a_triangle_around_the_vertex_outside_the_fan_is_refused_with_a_reused_index_too() {
    let f = model::stress::family("watertight-vertices").unwrap();
    let case = f.case(1, f.test_size);
    assert!(case.check_claims().is_empty());
    let (claim, member) = case
        .claims
        .iter()
        .find_map(|c| match c {
            Claim::ThroughSharedVertex { fan, .. } => Some((c, fan[0])),
            _ => None,
        })
        .expect("a vertex claim");
    let mut index = model::stress::FanIndex::default();
    assert!(claim.check_indexed(&case, &mut index).is_ok());
    let mut bad = case.clone();
    if let model::scene::GeometryData::Triangles(t) =
        &mut bad.scene.bottom_levels[0].geometries[member.0 as usize].data
    {
        let p = member.1 as usize;
        match &mut t.indices {
            Some(model::scene::Indices::U16(v)) => {
                let tri = [v[3 * p], v[3 * p + 1], v[3 * p + 2]];
                v.extend(tri);
            }
            Some(model::scene::Indices::U32(v)) => {
                let tri = [v[3 * p], v[3 * p + 1], v[3 * p + 2]];
                v.extend(tri);
            }
            None => {
                let tri = [
                    t.positions[3 * p],
                    t.positions[3 * p + 1],
                    t.positions[3 * p + 2],
                ];
                t.positions.extend(tri);
            }
        }
    }
    for e in [
        claim.check(&bad).unwrap_err(),
        claim.check_indexed(&bad, &mut index).unwrap_err(),
    ] {
        assert!(e.to_string().contains("not in the fan"), "{e}");
    }
}
