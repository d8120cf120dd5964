//! Meta-test: every generated valid case gets an empty verdict, on every committed profile, for every
//! command the profile supports (and a clear "unsupported by profile" for the others).

mod common;

use generator::{generate, CaseSpec, GenError};
use model::CommandId;

#[test]
fn valid_cases_have_empty_verdicts_on_every_profile() {
    let n = common::per_spec();
    let mut judged = 0;
    for (name, profile) in common::profiles() {
        for command in CommandId::TRACE {
            for spec in [
                CaseSpec::valid(command),
                CaseSpec::valid(command).at_limits(),
            ] {
                let cases = match generate(&profile, &name, common::rules(), &spec, n, 7) {
                    Ok(c) => c,
                    Err(GenError::Unsupported(why)) => {
                        assert!(command.is_nv(), "only NV may be unsupported here: {why}");
                        continue;
                    }
                    Err(e) => panic!("{name} {command:?}: {e}"),
                };
                for case in &cases {
                    let v = common::judge(&profile, case);
                    assert!(
                        v.is_valid(),
                        "{name}: {} judged invalid: {:?}\n{}",
                        case.name,
                        v.violations,
                        case.to_yaml()
                    );
                    judged += 1;
                }
            }
        }
    }
    assert!(judged >= 4 * common::per_spec(), "judged {judged}");
}

#[test]
fn nv_is_unsupported_without_the_extension() {
    let (name, profile) = common::profiles()
        .into_iter()
        .find(|(n, _)| n == "lavapipe")
        .unwrap();
    if profile.has_extension("VK_NV_ray_tracing") {
        return assert!(generate(
            &profile,
            &name,
            common::rules(),
            &CaseSpec::valid(CommandId::TraceRaysNv),
            1,
            1
        )
        .is_ok());
    }
    let err = generate(
        &profile,
        &name,
        common::rules(),
        &CaseSpec::valid(CommandId::TraceRaysNv),
        1,
        1,
    )
    .unwrap_err();
    assert!(
        err.to_string().starts_with("unsupported by profile"),
        "{err}"
    );
}

#[test]
fn generation_is_deterministic_and_names_carry_the_seed() {
    let (name, profile) = common::profiles()
        .into_iter()
        .find(|(n, _)| n == "lavapipe")
        .unwrap();
    let spec = CaseSpec::valid(CommandId::TraceRaysIndirect);
    let a = generate(&profile, &name, common::rules(), &spec, 20, 42).unwrap();
    let b = generate(&profile, &name, common::rules(), &spec, 20, 42).unwrap();
    let c = generate(&profile, &name, common::rules(), &spec, 20, 43).unwrap();
    assert_eq!(a, b);
    assert_ne!(a, c);
    assert_eq!(a[3].name, "trace-indirect-valid-42-3");
    assert_eq!(a[3].seed.as_deref(), Some("42/3"));
    assert_eq!(a[3].profile, "lavapipe");
}

#[test]
fn cases_generated_a_slice_at_a_time_are_the_cases_generated_at_once() {
    // `rtconf gen` and `rtconf run` generate long runs a slice at a time: the slices must give the
    // same cases at the same indices, for the trace commands, the build and a violated VUID.
    let (name, profile) = common::profiles()
        .into_iter()
        .find(|(n, _)| n == "lavapipe")
        .unwrap();
    let specs = [
        CaseSpec::valid(CommandId::TraceRaysIndirect),
        CaseSpec::valid(CommandId::BuildAccelerationStructuresIndirect),
        CaseSpec::for_vuid(
            "VUID-vkCmdTraceRaysIndirectKHR-stride-03686",
            CommandId::TraceRaysIndirect,
        ),
    ];
    for spec in &specs {
        let whole = generate(&profile, &name, common::rules(), spec, 30, 7).unwrap();
        assert!(!whole.is_empty(), "{spec:?}");
        let mut sliced = Vec::new();
        for range in [0..4, 4..5, 5..17, 17..30] {
            sliced.extend(
                generator::generate_range(&profile, &name, common::rules(), spec, range, 7)
                    .unwrap(),
            );
        }
        // Compared as written: a build's inactive primitives hold NaN, which `==` never equals.
        let names = |v: &[model::Case]| v.iter().map(|c| c.name.clone()).collect::<Vec<_>>();
        assert_eq!(names(&sliced), names(&whole), "{spec:?}");
        for (a, b) in sliced.iter().zip(&whole) {
            assert_eq!(a.to_yaml(), b.to_yaml(), "{}", a.name);
        }
    }
}

#[test]
fn valid_cases_cover_the_interesting_shapes() {
    use model::world::HandleRef;
    let (name, profile) = common::profiles()
        .into_iter()
        .find(|(n, _)| n == "lavapipe")
        .unwrap();
    let cases = generate(
        &profile,
        &name,
        common::rules(),
        &CaseSpec::valid(CommandId::TraceRaysIndirect),
        300,
        3,
    )
    .unwrap();
    let has = |f: &dyn Fn(&model::TraceBody) -> bool| {
        cases.iter().filter(|c| f(c.as_trace().unwrap())).count()
    };
    let zero_dim = has(&|c| c.call.dimensions(&c.world).is_some_and(|d| d.contains(&0)));
    let aabb = has(&|c| {
        c.world.launch.scene.bottom_levels.iter().any(|b| {
            b.geometries
                .iter()
                .any(|g| matches!(g.data, model::scene::GeometryData::Aabbs(_)))
        })
    });
    let zero_handle = has(&|c| {
        c.world.buffers.iter().any(|b| b.contents.iter().any(|x| matches!(x, model::world::Contents::ShaderRecords { handles, .. } if handles.contains(&HandleRef::Zero))))
    });
    let unused_miss = has(&|c| {
        c.call
            .region(model::Table::Miss)
            .is_some_and(|r| r.size == 0)
    });
    let no_null = has(&|c| {
        c.world
            .pipeline
            .as_ref()
            .is_some_and(|p| !p.flags.names().is_empty())
    });
    for (what, n) in [
        ("zero dimension", zero_dim),
        ("AABB geometry", aabb),
        ("zero handle", zero_handle),
        ("unused miss", unused_miss),
        ("NO_NULL flags", no_null),
    ] {
        assert!(n >= 10, "only {n} of 300 cases have a {what}");
    }
}

/// A device may report limits below what the specification requires (a conformance finding the run
/// prints): the valid cases keep to what it reports, and a profile on which no shader binding table
/// is valid gets "unsupported by profile", never a "valid" case its own model refuses.
#[test]
fn valid_cases_keep_to_limits_below_the_required_ones() {
    use model::profile::PropertyValue;
    let (name, base) = common::profiles()
        .into_iter()
        .find(|(n, _)| n == "lavapipe")
        .unwrap();
    let khr = "VkPhysicalDeviceRayTracingPipelinePropertiesKHR::";
    let with = |member: &str, v: PropertyValue| {
        let mut p = base.clone();
        p.properties.insert(member.to_string(), v);
        p
    };
    let low = [
        with(
            &format!("{khr}maxRayDispatchInvocationCount"),
            PropertyValue::Int(3),
        ),
        with(
            &format!("{khr}maxRayDispatchInvocationCount"),
            PropertyValue::Int(0),
        ),
        with(
            "VkPhysicalDeviceLimits::maxComputeWorkGroupCount",
            PropertyValue::Array(vec![
                PropertyValue::Int(1),
                PropertyValue::Int(0),
                PropertyValue::Int(2),
            ]),
        ),
    ];
    for profile in &low {
        assert!(!model::required_limits::findings(profile).is_empty());
        for command in [CommandId::TraceRaysIndirect, CommandId::TraceRays] {
            let cases = generate(
                profile,
                &name,
                common::rules(),
                &CaseSpec::valid(command),
                60,
                11,
            )
            .unwrap_or_else(|e| panic!("{command:?}: {e}"));
            for case in &cases {
                let v = common::judge(profile, case);
                assert!(v.is_valid(), "{}: {:?}", case.name, v.violations);
            }
        }
    }
    let narrow = with(&format!("{khr}maxShaderGroupStride"), PropertyValue::Int(8));
    match generate(
        &narrow,
        &name,
        common::rules(),
        &CaseSpec::valid(CommandId::TraceRaysIndirect),
        5,
        1,
    ) {
        Err(GenError::Unsupported(why)) => {
            assert!(
                why.contains("maximum shader group stride of 8 bytes"),
                "{why}"
            )
        }
        other => panic!("expected unsupported, got {:?}", other.map(|c| c.len())),
    }
}
