//! Doctored observations fed to the session's comparison, end to end: a launch is run on lavapipe,
//! its true records pass, and each planted fault — a hit turned into a miss on an unambiguous ray,
//! swapped primitive or instance IDs, t off by twice its bound, an instance transform not inverted,
//! facing inverted, a mask ignored, terminate-on-first-hit ignored — makes the case fail.

mod common;

use common::{committed, Lavapipe, DEVICE};
use harness::observe::Output;
use harness::TraceCheck;
use model::scene::{
    BottomLevel, Geometry, GeometryData, GeometryFlags, Ray, RayFlags, Scene, SceneInstance,
    Transform3x4, Triangles,
};
use model::tracer::record::RayRecord as R;
use model::world::ShaderGroup;
use model::Case;
use session::{compare, Outcome};

/// The index of word `word` of launch ID `id`'s record.
fn at(id: usize, word: usize) -> usize {
    id * R::WORDS + word
}

fn triangles(positions: Vec<[f32; 3]>, opaque: bool) -> BottomLevel {
    BottomLevel {
        geometries: vec![Geometry {
            flags: GeometryFlags {
                opaque,
                no_duplicate_any_hit: false,
            },
            data: GeometryData::Triangles(Triangles {
                positions,
                indices: None,
                transform: None,
            }),
        }],
    }
}

fn ray_at(x: f32, y: f32) -> Ray {
    Ray::new([x, y, -1.0], [0.0, 0.0, 1.0], 0.0, 100.0)
}

/// The hand-made indirect case (8 launch IDs, hit group 3 now with an accepting any-hit shader) with
/// a scene of five instances and one ray per launch ID.
fn case() -> Case {
    let mut c = committed("hand/trace-indirect-records-32.yaml");
    c.name = "doctored".into();
    let t = c.as_trace_mut().unwrap();
    if let Some(ShaderGroup::TrianglesHit { any_hit, .. }) =
        t.world.pipeline.as_mut().unwrap().groups.get_mut(3)
    {
        *any_hit = true;
    }
    let pair = triangles(
        vec![
            [-1.0, -1.0, 0.0],
            [0.0, -1.0, 0.0],
            [-0.5, 1.0, 0.0],
            [0.5, -1.0, 0.0],
            [1.5, -1.0, 0.0],
            [1.0, 1.0, 0.0],
        ],
        true,
    );
    let raised = triangles(
        vec![[-1.0, -1.0, 0.5], [1.0, -1.0, 0.5], [0.0, 1.0, 0.5]],
        true,
    );
    let stacked = triangles(
        vec![
            [-1.0, -1.0, 0.0],
            [1.0, -1.0, 0.0],
            [0.0, 1.0, 0.0],
            [-1.0, -1.0, 1.0],
            [1.0, -1.0, 1.0],
            [0.0, 1.0, 1.0],
        ],
        false,
    );
    let at = |b: u32, x: f32, y: f32, custom: u32| SceneInstance {
        transform: Transform3x4::translation([x, y, 0.0]),
        custom_index: custom,
        ..SceneInstance::of(b)
    };
    let mut scaled = at(1, 0.0, 8.0, 3);
    for r in 0..3 {
        scaled.transform.0[r][r] = 2.0;
    }
    t.world.launch.scene = Scene {
        bottom_levels: vec![pair, raised, stacked],
        instances: vec![
            at(0, 0.0, 0.0, 10),
            at(0, 0.0, 4.0, 11),
            SceneInstance {
                mask: 0x01,
                ..at(0, 0.0, 12.0, 12)
            },
            scaled,
            at(2, 0.0, 16.0, 14),
        ],
    };
    t.world.launch.rays = vec![
        ray_at(-0.5, 0.0),
        ray_at(1.0, 0.0),
        ray_at(-0.5, 4.0),
        ray_at(-50.0, -50.0),
        Ray {
            cull_mask: 0x02,
            ..ray_at(-0.5, 12.0)
        },
        ray_at(0.0, 8.0),
        ray_at(0.0, 16.0).with_flags(RayFlags::TERMINATE_ON_FIRST_HIT),
        ray_at(-0.5, 0.0),
    ];
    c
}

#[test]
fn planted_faults_in_the_records_are_caught_and_the_true_records_pass() {
    let _one = DEVICE.lock().unwrap_or_else(|e| e.into_inner());
    let mut lvp = Lavapipe::new();
    let case = case();
    let ran = lvp.run(&case, TraceCheck::Auto);
    assert_eq!(ran.report.outcome, Outcome::Pass, "{}", ran.report.detail);
    let obs = ran.observation.clone().unwrap();
    let words = obs.words().unwrap().to_vec();
    let rec = |id: usize| R::from_words(&words[id * R::WORDS..(id + 1) * R::WORDS]).unwrap();
    // What the driver did is what the scene was built for.
    assert_eq!(
        (rec(0).outcome, rec(0).primitive_id),
        (model::tracer::record::RecordOutcome::Hit, 0)
    );
    assert_eq!((rec(1).instance_id, rec(1).primitive_id), (0, 1));
    assert_eq!(rec(2).instance_id, 1);
    assert_eq!(rec(3).outcome, model::tracer::record::RecordOutcome::Miss);
    assert_eq!(rec(4).outcome, model::tracer::record::RecordOutcome::Miss);
    assert_eq!((rec(5).instance_id, rec(5).t), (3, 2.0));
    assert!(rec(6).any_hit_count <= 1, "{:?}", rec(6));

    let judge = |w: &[u32]| {
        let mut o = obs.clone();
        o.output = Some(Output::Words(w.to_vec()));
        let verdict = lvp.rules.judge(&lvp.profile, &case.body);
        compare(&case, &lvp.profile, &verdict, &o, &lvp.triage, 0.0)
    };
    assert_eq!(judge(&words).outcome, Outcome::Pass);
    let expected = model::semantics::expected_launch(
        &case.as_trace().unwrap().world,
        &case.as_trace().unwrap().call,
    )
    .unwrap();
    let t_report = expected.allowed[0].candidates[0].reports[0];
    type Fault = Box<dyn Fn(&mut [u32])>;
    let faults: Vec<(&str, Fault)> = vec![
        (
            "a hit turned into a miss",
            Box::new(|w| {
                w[at(0, R::OUTCOME)] = R::MISS;
                w[at(0, R::GROUP)] = 1;
            }),
        ),
        (
            "swapped primitive IDs",
            Box::new(|w| w.swap(at(0, R::PRIMITIVE_ID), at(1, R::PRIMITIVE_ID))),
        ),
        (
            "swapped instance IDs",
            Box::new(|w| {
                w.swap(at(0, R::INSTANCE_ID), at(2, R::INSTANCE_ID));
                w.swap(at(0, R::CUSTOM_INDEX), at(2, R::CUSTOM_INDEX));
            }),
        ),
        (
            "t off by twice its bound",
            Box::new(move |w| {
                let t = t_report.t_exact + 2.0 * t_report.t.radius().max(f32::EPSILON as f64);
                w[at(0, R::T)] = (t as f32).to_bits();
            }),
        ),
        (
            // A driver applying the instance transform to the ray instead of its inverse meets the
            // raised triangle (z = 0.5 in object space) at t = 1.25, not 2.
            "an instance transform not inverted",
            Box::new(|w| w[at(5, R::T)] = 1.25f32.to_bits()),
        ),
        ("facing inverted", Box::new(|w| w[at(0, R::HIT_KIND)] ^= 1)),
        (
            "a mask ignored",
            Box::new(|w| {
                let hit: Vec<u32> = w[at(0, 0)..at(1, 0)].to_vec();
                w[at(4, 0)..at(5, 0)].copy_from_slice(&hit);
                w[at(4, R::INSTANCE_ID)] = 2;
                w[at(4, R::CUSTOM_INDEX)] = 12;
            }),
        ),
        (
            "terminate-on-first-hit ignored",
            Box::new(|w| {
                w[at(6, R::ANY_HIT_COUNT)] = 2;
                for (n, (prim, t)) in [(0u32, 1.0f32.to_bits()), (1, 2.0f32.to_bits())]
                    .into_iter()
                    .enumerate()
                {
                    let s = at(6, R::SEEN + 4 * n);
                    w[s..s + 4].copy_from_slice(&[4, 0, prim, t]);
                }
            }),
        ),
    ];
    // The pictures of a failing case: three images of the launch, red where the fault is.
    let mut w = words.clone();
    faults[0].1(&mut w);
    let dir = tempfile::tempdir().unwrap();
    let written = session::pictures::write(dir.path(), "doctored", case.as_trace().unwrap(), &w);
    assert_eq!(written.len(), 3, "{written:?}");
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(dir.path().join("doctored-diff.png")).unwrap(),
    ));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (4, 2));
    assert_eq!(&buf[0..3], &[255, 0, 0], "launch ID 0 is the fault");
    assert_ne!(&buf[3..6], &[255, 0, 0], "launch ID 1 is not");
    for (what, fault) in faults {
        let mut w = words.clone();
        fault(&mut w);
        assert_ne!(w, words, "{what}: the fault changes the records");
        let report = judge(&w);
        assert_eq!(report.outcome, Outcome::Fail, "{what} was not caught");
        assert!(
            report.detail.contains("launch ID"),
            "{what}: {}",
            report.detail
        );
    }
}
