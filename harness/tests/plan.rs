//! The call plan against the model it is made from, with no device: every committed build case's
//! memory images, laid out from the plan with any addresses, are the model's own images with those
//! addresses; every committed trace case and every trace case a run of the committed profiles
//! generates (lavapipe's, and the H200's with its vkCmdTraceRaysNV cases) is described — its scene
//! (bottom levels, instance records, spheres), rays and records as the model states them, its steps
//! around exactly one call, its call list naming the scene's builds; a command buffer of a pool without
//! compute (the H200's transfer families) holding the call alone, its pipeline's shader bodies full
//! exactly when it is submitted — and the buffer plans write shader records and indirect commands
//! where the world says.

use harness::plan::scene::{GeometryDataPlan, ScenePlan};
use harness::plan::trace::{buffer_plans, BufferWrite, TracePlan, RAY_RECORD_SIZE};
use harness::plan::{CallPlan, PlanBody, ShaderBody, Step};
use harness::Execution;
use model::accel::world::{AddressResolver, SyntheticAddresses};
use model::flags::QueueFlags;
use model::tracer::record::RayRecord;
use model::world::Contents;
use model::Case;
use std::collections::BTreeMap;
use std::path::Path;

fn committed(folder: &str) -> Vec<Case> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../cases")
        .join(folder);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "yaml"))
        .collect();
    files.sort();
    files
        .iter()
        .map(|p| {
            let text = std::fs::read_to_string(p).unwrap();
            Case::from_yaml(&p.display().to_string(), &text).unwrap()
        })
        .collect()
}

/// Addresses unlike the model's synthetic ones: buffer `k` at `0x1_0000 * (k + 3)`, structure `s` at
/// `0x7000_0000 + 0x100 * s`.
struct Elsewhere<'w>(&'w model::accel::BuildWorld);

impl AddressResolver for Elsewhere<'_> {
    fn buffer(&self, name: &str) -> Option<u64> {
        let k = self.0.buffers.iter().position(|b| b.name == name)?;
        Some(0x1_0000 * (k as u64 + 3))
    }
    fn structure(&self, name: &str) -> Option<u64> {
        let s = self.0.structures.iter().position(|x| x.name == name)?;
        Some(0x7000_0000 + 0x100 * s as u64)
    }
}

#[test]
fn build_plans_lay_out_the_models_memory_images_at_any_addresses() {
    let cases = committed("build");
    assert!(cases.len() >= 40, "{} build cases", cases.len());
    let mut relocated = 0;
    for case in &cases {
        let body = case.as_accel().expect("a build case");
        let plan = CallPlan::of(case, &Execution::default()).expect("a plan");
        let PlanBody::Build(b) = &plan.body else {
            panic!("{}: not a build plan", case.name)
        };
        assert_eq!(b.buffers.len(), body.world.buffers.len());
        for buffer in &b.buffers {
            relocated += buffer.relocations.len();
            let synthetic = SyntheticAddresses(&body.world);
            let elsewhere = Elsewhere(&body.world);
            for r in [&synthetic as &dyn AddressResolver, &elsewhere] {
                assert_eq!(
                    buffer.image_at(r),
                    body.world.image(&buffer.name, r).unwrap(),
                    "{}: buffer {}",
                    case.name,
                    buffer.name
                );
            }
        }
        let calls = b
            .steps
            .iter()
            .filter(|s| matches!(s, Step::Call { .. }))
            .count();
        assert_eq!(calls, 1, "{}: one call", case.name);
    }
    assert!(relocated > 0, "some committed case holds device addresses");
}

/// Checks a trace case's plan against its case; returns it.
fn check_trace_plan(case: &Case, exec: &Execution) -> Result<TracePlan, String> {
    let body = case.as_trace().expect("a trace case");
    let plan = match CallPlan::of(case, exec) {
        Ok(p) => p,
        Err(harness::HarnessError::NotRealised(why)) => return Err(why),
        Err(e) => panic!("{}: {e}", case.name),
    };
    let PlanBody::Trace(t) = &plan.body else {
        panic!("{}: not a trace plan", case.name)
    };
    let world = &body.world;
    assert_eq!(t.traces, world.launch.traces(), "{}", case.name);
    // Only a case that is submitted runs its shaders: the others get the interface-only bodies.
    if let Some(p) = &t.pipeline {
        let want = if exec.run_valid {
            ShaderBody::Full
        } else {
            ShaderBody::InterfaceOnly
        };
        assert_eq!(p.body, want, "{}", case.name);
        // The plan as a person reads it says so.
        let said = plan
            .describe()
            .iter()
            .any(|l| l.contains("interface-only shader bodies"));
        assert_eq!(said, !exec.run_valid, "{}", case.name);
    }
    if world
        .command_buffer
        .pool_queue
        .contains(QueueFlags::COMPUTE_BIT)
    {
        assert_eq!((t.pool_family, plan.device.pool_family), (None, None));
    } else {
        check_pool_without_compute(case, t, plan.device.pool_family);
    }
    let rays = if t.traces {
        world.launch.ray_list()
    } else {
        vec![]
    };
    let header: Vec<u32> = t.io.rays[..16]
        .chunks(4)
        .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    assert_eq!(header[0] as usize, rays.len(), "{}", case.name);
    assert_eq!(header[1] as usize, t.io.records, "{}", case.name);
    assert_eq!(
        t.io.rays.len(),
        16 + rays.len() * RAY_RECORD_SIZE,
        "{}",
        case.name
    );
    for (k, r) in rays.iter().enumerate().take(64) {
        let at = 16 + k * RAY_RECORD_SIZE;
        let f = |i: usize| {
            f32::from_le_bytes(t.io.rays[at + 4 * i..at + 4 * i + 4].try_into().unwrap())
        };
        assert_eq!(
            [f(0), f(1), f(2), f(3), f(4), f(5), f(6), f(7)].map(f32::to_bits),
            [
                r.origin[0],
                r.origin[1],
                r.origin[2],
                r.tmin,
                r.direction[0],
                r.direction[1],
                r.direction[2],
                r.tmax
            ]
            .map(f32::to_bits),
            "{}: ray {k}",
            case.name
        );
    }
    let ids = body.call.dimensions(world).map_or(0, |d| {
        d.iter()
            .map(|&x| x as usize)
            .fold(1usize, usize::saturating_mul)
    });
    assert_eq!(t.launch_ids, ids, "{}", case.name);
    assert_eq!(
        t.io.output_words,
        (t.io.records * RayRecord::WORDS).max(RayRecord::WORDS)
    );
    let calls = t
        .steps
        .iter()
        .filter(|s| matches!(s, Step::Call { .. }))
        .count();
    assert_eq!(calls, 1, "{}: one call", case.name);
    let read_back = t.steps.iter().find_map(|s| match s {
        Step::ReadBack { words } => Some(*words),
        _ => None,
    });
    if let Some(words) = read_back {
        assert!(exec.run_valid, "{}", case.name);
        assert_eq!(words, ids * RayRecord::WORDS, "{}", case.name);
    }
    match &t.scene {
        None => assert!(!t.traces, "{}", case.name),
        Some(s) => {
            let scene = &world.launch.scene;
            assert_eq!(*s, ScenePlan::of(scene, t.api), "{}", case.name);
            assert_eq!(s.bottoms.len(), scene.bottom_levels.len());
            assert_eq!(s.instances.len(), scene.instances.len());
            for (bl, model_bl) in s.bottoms.iter().zip(&scene.bottom_levels) {
                for (g, m) in bl.geometries.iter().zip(&model_bl.geometries) {
                    // The positions (or boxes) at the plan's offset are the model's.
                    let (offset, floats): (u64, Vec<f32>) = match (&g.data, &m.data) {
                        (
                            GeometryDataPlan::Triangles { vertices, .. },
                            model::scene::GeometryData::Triangles(tri),
                        ) => (*vertices, tri.positions.iter().flatten().copied().collect()),
                        (
                            GeometryDataPlan::Aabbs { boxes, .. },
                            model::scene::GeometryData::Aabbs(a),
                        ) => (
                            *boxes,
                            a.boxes
                                .iter()
                                .flat_map(|b| b.min.into_iter().chain(b.max))
                                .collect(),
                        ),
                        _ => panic!("{}: a geometry of another kind", case.name),
                    };
                    let bytes: Vec<u8> = floats.iter().flat_map(|x| x.to_le_bytes()).collect();
                    let o = offset as usize;
                    assert_eq!(&s.input[o..o + bytes.len()], &bytes[..], "{}", case.name);
                }
            }
            for (i, (p, m)) in s.instances.iter().zip(&scene.instances).enumerate() {
                assert_eq!(p.mask, m.mask, "{}: instance {i}", case.name);
                assert_eq!(p.custom_index, m.custom_index & 0xFF_FFFF);
                assert_eq!(p.sbt_record_offset, m.sbt_record_offset & 0xFF_FFFF);
                if p.bottom.is_some() {
                    assert_eq!(p.bottom.map(|b| b as u32), m.bottom_level);
                }
            }
            let lines = plan.describe();
            assert!(
                lines.iter().any(|l| l.contains(": top level of")),
                "{}: the call list names the scene's builds: {lines:#?}",
                case.name
            );
            assert_eq!(
                lines
                    .iter()
                    .filter(|l| l.contains(": bottom level "))
                    .count(),
                s.built_bottoms(),
                "{}",
                case.name
            );
        }
    }
    Ok(t.clone())
}

/// What the harness refuses to realise, and so the plan refuses: the reasons it may give.
const REFUSALS: [&str; 11] = [
    "cannot be called",
    "the case traces rays but does not enable",
    "video coding scopes and protected command buffers are not realised",
    "an invalid command buffer of a pool without compute is not realised",
    "a command buffer of a pool without compute is never submitted",
    "a pipeline bound in a pool without compute",
    "a resource state in a pool without compute",
    "a render pass in a pool without compute is not realised",
    "secondary command buffers inside a render pass are not realised",
    "is larger than the harness reads back",
    "procedural without an intersection shader",
];

/// A plan whose command buffer comes from a pool of a family without compute records the call alone
/// there: its steps are a begin, an end where the case is executable, and the call (dropped).
fn check_pool_without_compute(case: &Case, t: &TracePlan, device_pool: Option<QueueFlags>) {
    let cbs = &case.as_trace().expect("a trace case").world.command_buffer;
    assert_eq!(t.pool_family, Some(cbs.pool_queue), "{}", case.name);
    assert_eq!(
        device_pool, t.pool_family,
        "{}: the device gets its queue",
        case.name
    );
    for s in &t.steps {
        assert!(
            matches!(
                s,
                Step::Begin { .. } | Step::End | Step::Call { dropped: true }
            ),
            "{}: {s:?} recorded in a pool without compute",
            case.name
        );
    }
}

#[test]
fn committed_trace_cases_are_described_by_the_call_plan() {
    let mut cases = committed("hand");
    cases.extend(committed("edge"));
    cases.extend(committed("rendered"));
    cases.extend(committed("nvidia-h200"));
    let mut described = 0;
    for case in &cases {
        let exec = Execution {
            run_valid: case.intent == model::Intent::Valid,
            ..Default::default()
        };
        match check_trace_plan(case, &exec) {
            Ok(_) => described += 1,
            Err(why) => assert!(
                REFUSALS.iter().any(|r| why.contains(r)),
                "{}: refused: {why}",
                case.name
            ),
        }
    }
    assert!(
        described >= cases.len() - 2,
        "{described} of {}",
        cases.len()
    );
}

/// The rule table of the installed registry.
fn installed_rules() -> model::RuleSet {
    let set = vk_registry::source::load_union(&[std::path::PathBuf::from(
        vk_registry::source::DEFAULT_REGISTRY_DIR,
    )])
    .expect("the installed registry");
    model::RuleSet::from_vuids(&set)
}

#[test]
fn every_generated_trace_case_of_the_committed_profiles_is_planned() {
    let rules = installed_rules();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../profiles");
    let mut totals: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    let mut refused: BTreeMap<String, usize> = BTreeMap::new();
    let mut nv_planned = 0;
    // Cases whose pool's family lacks compute, per trace command: planned (on the H200's transfer
    // families) and refused.
    let mut pool_planned: BTreeMap<&str, usize> = BTreeMap::new();
    let mut pool_refused = 0;
    let (mut not_generated, mut kept_from_drivers) = (0, 0);
    for name in ["lavapipe", "nvidia-h200"] {
        let text = std::fs::read_to_string(dir.join(format!("{name}.json"))).unwrap();
        let profile = model::DeviceProfile::from_profiles_json(name, &text).unwrap();
        for command in model::CommandId::TRACE {
            if command.is_nv() && !profile.has_extension("VK_NV_ray_tracing") {
                continue;
            }
            let mut specs = vec![
                (generator::CaseSpec::valid(command), 5),
                (generator::CaseSpec::rendered(command), 20),
            ];
            for row in rules.rows.iter().filter(|r| {
                r.status == model::rules::Status::Executable
                    && model::rules::applies_to(&r.scope, command)
            }) {
                if generator::mutations_for(&row.vuid).is_some() {
                    specs.push((generator::CaseSpec::violate(command, &row.vuid), 3));
                }
            }
            for (i, (spec, count)) in specs.iter().enumerate() {
                let Ok(cases) =
                    generator::generate(&profile, name, &rules, spec, *count, 7 + i as u64)
                else {
                    // A VUID this profile cannot express (the generator says so): no case.
                    not_generated += 1;
                    continue;
                };
                for case in &cases {
                    if case.runnable(&profile).is_err() {
                        kept_from_drivers += 1;
                        continue;
                    }
                    let exec = Execution::for_case(case, &profile);
                    let key = format!("{name} {}", command.vk_name());
                    let entry = totals.entry(key).or_default();
                    let pool_without_compute = !case
                        .as_trace()
                        .expect("a trace case")
                        .world
                        .command_buffer
                        .pool_queue
                        .contains(QueueFlags::COMPUTE_BIT);
                    match check_trace_plan(case, &exec) {
                        Ok(t) => {
                            entry.0 += 1;
                            if t.api == model::world::PipelineApi::Nv {
                                nv_planned += 1;
                            }
                            if pool_without_compute {
                                *pool_planned.entry(command.vk_name()).or_default() += 1;
                            }
                        }
                        Err(why) => {
                            entry.1 += 1;
                            if pool_without_compute {
                                pool_refused += 1;
                            }
                            assert!(
                                REFUSALS.iter().any(|r| why.contains(r)),
                                "{}: refused: {why}",
                                case.name
                            );
                            *refused.entry(why).or_default() += 1;
                        }
                    }
                }
            }
        }
    }
    eprintln!("described, refused per profile and command: {totals:#?}");
    eprintln!("refusals: {refused:#?}");
    eprintln!(
        "specs the profile cannot express: {not_generated}; cases kept from drivers: {kept_from_drivers}"
    );
    let (ok, no): (usize, usize) = totals
        .values()
        .fold((0, 0), |(a, b), (x, y)| (a + x, b + y));
    assert!(ok > 1000, "{ok} trace cases described");
    assert!(no * 20 < ok, "{no} refused of {}", ok + no);
    assert!(nv_planned > 20, "{nv_planned} NV cases planned");
    // The H200 has transfer-only families: its pool-without-compute cases (commandBuffer-cmdpool of
    // every trace command) are planned, none refused.
    eprintln!("pools without compute: planned {pool_planned:?}, refused {pool_refused}");
    assert_eq!(pool_refused, 0, "cases of a pool without compute refused");
    for command in model::CommandId::TRACE {
        assert!(
            pool_planned.get(command.vk_name()).copied().unwrap_or(0) >= 3,
            "{}: {pool_planned:?}",
            command.vk_name()
        );
    }
    for (key, (ok, _)) in &totals {
        assert!(*ok > 0, "{key}: no case described");
    }
}

#[test]
fn trace_buffers_are_written_where_the_world_says() {
    let mut cases = committed("hand");
    cases.extend(committed("edge"));
    cases.extend(committed("rendered"));
    for case in &cases {
        let body = case.as_trace().expect("a trace case");
        let buffers = buffer_plans(&body.world);
        assert_eq!(buffers.len(), body.world.buffers.len(), "{}", case.name);
        for (b, world) in buffers.iter().zip(&body.world.buffers) {
            assert_eq!(b.name, world.name);
            assert_eq!(b.size, world.size);
            let handles: usize = world
                .contents
                .iter()
                .map(|c| match c {
                    Contents::ShaderRecords { handles, .. } => handles.len(),
                    _ => 0,
                })
                .sum();
            let written = b
                .writes
                .iter()
                .filter(|w| matches!(w, BufferWrite::Handle { .. }))
                .count();
            assert_eq!(handles, written, "{}: {}", case.name, b.name);
            for w in &b.writes {
                if let BufferWrite::Handle { offset, handle } = w {
                    assert_eq!(
                        body.world.handle_at(&b.name, *offset),
                        Some(*handle),
                        "{}: {} at {offset}",
                        case.name,
                        b.name
                    );
                }
            }
        }
    }
}

/// An NV table naming a buffer the world lacks (`*ShaderBindingTableBuffer-parameter`: a handle that
/// is no valid VkBuffer) is planned as a buffer created and destroyed before the call, for a case only
/// recorded; run as valid, it is refused.
#[test]
fn an_nv_table_naming_a_missing_buffer_gets_a_destroyed_handle() {
    let rules = installed_rules();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../profiles");
    let text = std::fs::read_to_string(dir.join("nvidia-h200.json")).unwrap();
    let profile = model::DeviceProfile::from_profiles_json("nvidia-h200", &text).unwrap();
    let mut planned = 0;
    for table in ["raygen", "miss", "hit", "callable"] {
        let vuid = format!("VUID-vkCmdTraceRaysNV-{table}ShaderBindingTableBuffer-parameter");
        let spec = generator::CaseSpec::violate(model::CommandId::TraceRaysNv, &vuid);
        let cases = generator::generate(&profile, "nvidia-h200", &rules, &spec, 4, 11)
            .unwrap_or_else(|e| panic!("{vuid}: {e}"));
        for case in &cases {
            let body = case.as_trace().expect("a trace case");
            let model::Call::TraceRaysNv(c) = &body.call else {
                panic!("{}: an NV call", case.name)
            };
            let missing: Vec<String> = [&c.raygen, &c.miss, &c.hit, &c.callable]
                .into_iter()
                .filter_map(|t| t.buffer.clone())
                .filter(|n| !body.world.buffers.iter().any(|b| &b.name == n))
                .collect();
            let plan = TracePlan::of(body, false).unwrap_or_else(|e| panic!("{}: {e}", case.name));
            let mut expected = missing.clone();
            expected.dedup();
            assert_eq!(plan.destroyed_buffers, expected, "{}", case.name);
            if missing.is_empty() {
                // The raygen table's null handle: nothing to destroy.
                continue;
            }
            planned += 1;
            let exec = Execution {
                run_valid: false,
                ..Default::default()
            };
            let lines = CallPlan::of(case, &exec)
                .unwrap_or_else(|e| panic!("{}: {e}", case.name))
                .describe();
            assert!(
                lines.iter().any(|l| l.contains("then vkDestroyBuffer")),
                "{}: {lines:#?}",
                case.name
            );
            let valid = TracePlan::of(body, true);
            assert!(
                matches!(&valid, Err(harness::HarnessError::NotRealised(why)) if why.contains("which the world lacks")),
                "{}: {valid:?}",
                case.name
            );
        }
    }
    assert!(planned >= 8, "{planned} cases name a missing buffer");
}

/// A primary command buffer stated executable or invalid inside a render pass instance is refused with
/// the End command's rule, for a build as for a trace: the harness reaches those states by ending the
/// command buffer, which a primary one cannot do inside a render pass instance, and ending the render
/// pass first would record the call outside it. The same states of a secondary command buffer that
/// continues a render pass are planned.
#[test]
fn a_primary_ended_inside_a_render_pass_is_not_realised() {
    use model::world::{CommandBufferLevel as V, CommandBufferLifecycle as L};
    let mut checked = 0;
    for mut case in committed("build")
        .into_iter()
        .filter(|c| c.name.contains("renderpass"))
        .chain(committed("hand").into_iter().take(1))
    {
        for lifecycle in [L::Executable, L::Invalid] {
            for level in [V::Primary, V::Secondary] {
                let cb = match &mut case.body {
                    model::case::Body::Trace(t) => &mut t.world.command_buffer,
                    model::case::Body::Accel(a) => &mut a.world.command_buffer,
                };
                cb.in_render_pass = true;
                cb.lifecycle = lifecycle;
                cb.level = level;
                let plan = CallPlan::of(&case, &Execution::default());
                let trace = case.as_trace().is_some();
                match (level, plan) {
                    (V::Primary, Err(harness::HarnessError::NotRealised(why))) => {
                        assert!(why.contains("00060"), "{}: {why}", case.name)
                    }
                    (V::Primary, other) => panic!("{} {lifecycle:?}: {other:?}", case.name),
                    // Traces leave every secondary inside a render pass to a later harness.
                    (V::Secondary, Err(harness::HarnessError::NotRealised(why))) if trace => {
                        assert!(why.contains("secondary"), "{why}")
                    }
                    (V::Secondary, plan) => {
                        assert!(plan.is_ok(), "{} {lifecycle:?}: {plan:?}", case.name)
                    }
                }
                checked += 1;
            }
        }
    }
    assert!(checked >= 8, "{checked}");
}
