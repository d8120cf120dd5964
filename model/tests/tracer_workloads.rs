//! The traversal's shortcuts change no answer: on the standard workloads (camera rays through
//! soups, a closed icosphere, a grid, instanced copies and spheres) the default tracer — BVH with
//! its padded-box bounds, the cut, the classification kept from the traversal — allows exactly the
//! outcomes of the brute-force tracer that tests every primitive in item order, and
//! `expected_launch` (distinct rays memoised, traced in parallel) exactly those of tracing each
//! launch ID's ray by itself through brute force.

use model::case::Case;
use model::scene::GeometryData;
use model::tracer::workload::{standard_workload, standard_workloads, workload_shaders};
use model::tracer::{
    trace_ray, MissShader, PreparedScene, Presence, ShaderTable, TracerConfig, TracerStats,
};
use model::world::Contents;

const SIDE: u32 = 16;

const BRUTE_FORCE: TracerConfig = TracerConfig {
    precision: model::tracer::Precision::F64WithExactFallback,
    use_bvh: false,
    far_test: true,
};

/// The counters that do not depend on how the primitives are reached.
fn classified(s: &TracerStats) -> [u64; 7] {
    [
        s.rays,
        s.pair_tests,
        s.filter_decided,
        s.exact_evaluations,
        s.req_hit,
        s.vary,
        s.req_miss,
    ]
}

#[test]
fn the_bvh_allows_what_brute_force_allows_on_every_standard_workload() {
    let table = ShaderTable {
        hit: &workload_shaders,
        miss: MissShader {
            zero_group: false,
            group: 0,
        },
    };
    let mut candidates = 0;
    let mut cut_rays = 0;
    for w in standard_workloads(SIDE, false) {
        let prepared = PreparedScene::new(&w.scene).expect("defined workload");
        let mut fast = TracerStats::default();
        let mut brute = TracerStats::default();
        let mut full = TracerStats::default();
        for (i, ray) in w.rays.iter().enumerate() {
            let a = trace_ray(&prepared, ray, &table, &TracerConfig::default(), &mut fast)
                .expect("defined ray");
            let b = trace_ray(&prepared, ray, &table, &BRUTE_FORCE, &mut brute).expect("defined");
            assert_eq!(a, b, "{}: ray {i} {ray:?}", w.name);
            // Every primitive classified in full, far or not (every twentieth ray): the far test only
            // removes pairs, never a required one, and changes none it keeps (it is sharper than
            // the classification, which may find a far grazing pair VARY).
            if i % 20 == 0 {
                let config = TracerConfig {
                    far_test: false,
                    ..BRUTE_FORCE
                };
                let c = trace_ray(&prepared, ray, &table, &config, &mut full).expect("defined");
                for x in &a.candidates {
                    assert_eq!(c.candidate(&x.primitive), Some(x), "{}: ray {i}", w.name);
                }
                for x in c
                    .candidates
                    .iter()
                    .filter(|x| x.presence == Presence::Required)
                {
                    assert_eq!(a.candidate(&x.primitive), Some(x), "{}: ray {i}", w.name);
                }
            }
            candidates += a.candidates.len();
            cut_rays += usize::from(!a.miss.allowed);
        }
        assert_eq!(classified(&fast), classified(&brute), "{}", w.name);
        assert!(
            fast.far_rejections < brute.far_rejections,
            "{}: the BVH reached fewer primitives than brute force",
            w.name
        );
    }
    // The camera rays hit: the comparison is about hits, not only misses.
    eprintln!("{candidates} candidates, {cut_rays} rays with a required hit");
    assert!(candidates > 500, "{candidates} candidates");
    assert!(cut_rays > 300, "{cut_rays} rays with a required hit");
}

fn hand_case() -> Case {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../cases/hand/trace-indirect-records-32.yaml");
    let text = std::fs::read_to_string(path).expect("the hand-made case");
    Case::from_yaml("hand", &text).expect("the hand-made case parses")
}

#[test]
fn expected_launch_allows_per_launch_id_what_brute_force_allows_its_ray() {
    let mut compared = 0;
    for w in standard_workloads(SIDE, false) {
        let triangles = w.scene.bottom_levels.iter().all(|b| {
            b.geometries
                .iter()
                .all(|g| matches!(g.data, GeometryData::Triangles(_)))
        });
        if !triangles {
            continue;
        }
        let mut case = hand_case();
        let t = case.as_trace_mut().expect("a trace case");
        t.world.launch.scene = w.scene.clone();
        // Every ray twice, the second copies in reverse: the memo of distinct rays is exercised.
        let mut rays = w.rays.clone();
        rays.extend(w.rays.iter().rev().copied());
        t.world.launch.rays = rays.clone();
        for b in &mut t.world.buffers {
            for c in &mut b.contents {
                if let Contents::TraceRaysIndirectCommand { width, height, .. } = c {
                    *width = SIDE;
                    *height = 2 * SIDE;
                }
            }
        }
        let body = case.as_trace().expect("a trace case");
        let expected = model::semantics::expected_launch(&body.world, &body.call)
            .expect("the workload's outcomes");
        assert_eq!(expected.rays, rays);
        assert_eq!(expected.allowed.len(), rays.len());
        let prepared = PreparedScene::new(&w.scene).expect("defined workload");
        let mut reference = TracerStats::default();
        for (i, ray) in rays.iter().enumerate() {
            let mut stats = TracerStats::default();
            let r = model::semantics::allowed_for_ray_with(
                &body.world,
                &body.call,
                &prepared,
                ray,
                &BRUTE_FORCE,
                &mut stats,
            )
            .expect("a defined ray");
            assert_eq!(expected.allowed[i], r, "{}: launch ID {i}", w.name);
            // The launch's counters are those of its distinct rays.
            if i < w.rays.len() {
                reference.merge(&stats);
            }
            compared += 1;
        }
        assert_eq!(
            classified(&expected.stats),
            classified(&reference),
            "{}",
            w.name
        );
    }
    assert_eq!(compared, 4 * 2 * (SIDE * SIDE) as usize);
}

#[test]
fn the_prepared_scene_memo_tells_scenes_apart_by_every_bit() {
    use model::scene::{GeometryData, Indices, Transform3x4};
    use model::semantics::{prepared, same_scene};
    let base = standard_workload(2, "instanced").scene;
    assert!(same_scene(&base, &base.clone()));
    fn triangles(s: &mut model::scene::Scene) -> &mut model::scene::Triangles {
        match &mut s.bottom_levels[0].geometries[0].data {
            GeometryData::Triangles(t) => t,
            GeometryData::Aabbs(_) => unreachable!("a triangle level"),
        }
    }
    // One change of each kind the tracer can see; each must make another scene.
    let mut changed: Vec<(&str, model::scene::Scene)> = Vec::new();
    let mut s = base.clone();
    triangles(&mut s).positions[7][1] =
        f32::from_bits(triangles(&mut s).positions[7][1].to_bits() + 1);
    changed.push(("one ulp of one vertex", s));
    let mut s = base.clone();
    let last = triangles(&mut s).positions.len() - 1;
    triangles(&mut s).positions[last][2] = -triangles(&mut s).positions[last][2];
    changed.push(("the sign of the last coordinate", s));
    let mut s = base.clone();
    match triangles(&mut s).indices.as_mut() {
        Some(Indices::U16(v)) => v.swap(0, 1),
        Some(Indices::U32(v)) => v.swap(0, 1),
        None => panic!("the icosphere is indexed"),
    }
    changed.push(("two indices swapped", s));
    let mut s = base.clone();
    triangles(&mut s).transform = Some(Transform3x4::IDENTITY);
    changed.push(("an identity geometry transform", s));
    let mut s = base.clone();
    s.bottom_levels[0].geometries[0].flags.opaque ^= true;
    changed.push(("the opaque flag", s));
    let mut s = base.clone();
    s.instances[3].transform.0[1][3] =
        f32::from_bits(s.instances[3].transform.0[1][3].to_bits() ^ 1);
    changed.push(("one bit of one instance's translation", s));
    let mut s = base.clone();
    s.instances[5].mask ^= 0x10;
    changed.push(("an instance mask", s));
    let mut s = base.clone();
    s.instances[5].flags.flip_facing ^= true;
    changed.push(("an instance flag", s));
    let mut s = base.clone();
    s.instances.pop();
    changed.push(("one instance fewer", s));
    for (what, s) in &changed {
        assert!(!same_scene(&base, s), "{what}: taken for the same scene");
        assert!(!same_scene(s, &base), "{what}: taken for the same scene");
    }
    // A zero of the other sign is another scene for the memo too.
    let mut zero = model::scene::Scene {
        bottom_levels: vec![model::scene::BottomLevel {
            geometries: vec![model::scene::Geometry {
                flags: Default::default(),
                data: GeometryData::Triangles(model::scene::Triangles {
                    positions: vec![[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]],
                    indices: None,
                    transform: None,
                }),
            }],
        }],
        instances: vec![model::scene::SceneInstance::of(0)],
    };
    let a = prepared(&zero).expect("a defined scene");
    triangles(&mut zero).positions[0][0] = -0.0;
    let b = prepared(&zero).expect("a defined scene");
    assert!(!std::sync::Arc::ptr_eq(&a, &b));
    assert_eq!(b.scene().bottom_levels, zero.bottom_levels);
    let c = prepared(&zero).expect("a defined scene");
    assert!(
        std::sync::Arc::ptr_eq(&b, &c),
        "the same scene is prepared once"
    );
}
