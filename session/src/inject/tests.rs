//! The injected copies differ from their cases only where each kind says, size 0 is the case itself,
//! choices are deterministic, and bad sizes are refused with what is wrong.

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
            // Deterministic in (case, injection, seed). Compared as text: an inactive box's NaN
            // coordinate is never equal to itself as a float.
            let again = inject(c, &Injection { kind, size }, &profile, 7).unwrap();
            assert_eq!(format!("{i:?}"), format!("{again:?}"));
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
                assert_eq!(format!("{:?}", i.case), format!("{c:?}"), "{kind}");
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
