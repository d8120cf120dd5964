//! The gate refuses a valid case whose scene or rays the spec leaves undefined, with each problem's
//! path in the case file located to its line and column.

use model::{Case, DeviceProfile};

fn lavapipe() -> DeviceProfile {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../profiles/lavapipe.json");
    DeviceProfile::from_profiles_json("lavapipe", &std::fs::read_to_string(p).unwrap()).unwrap()
}

fn hand_case_text() -> String {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../cases/hand/trace-indirect-records-32.yaml");
    std::fs::read_to_string(p).unwrap()
}

#[test]
fn undefined_rays_and_transforms_are_refused_with_located_paths() {
    let profile = lavapipe();
    let good = Case::from_yaml("hand.yaml", &hand_case_text()).unwrap();
    assert!(good.runnable(&profile).is_ok());
    // Ray 1 gets tmax below tmin; the instance a singular transform.
    let text = hand_case_text()
        .replacen(
            "- { origin: [-1000.0, -1000.0, -1.0], direction: [0.0, 0.0, 1.0], tmax: 100.0 }",
            "- { origin: [-1000.0, -1000.0, -1.0], direction: [0.0, 0.0, 1.0], tmin: 2.0, tmax: 1.0 }",
            1,
        )
        .replace(
            "- { bottom_level: 0 }",
            "- { bottom_level: 0, transform: [[1.0, 0.0, 0.0, 0.0], [2.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]] }",
        );
    let bad = Case::from_yaml("hand.yaml", &text).unwrap();
    let why = bad.runnable(&profile).expect_err("undefined scene");
    let located = why.located("hand.yaml", &text);
    let line_of = |needle: &str| 1 + text.lines().position(|l| l.contains(needle)).unwrap();
    let tmax_line = line_of("tmin: 2.0");
    let inst_line = line_of("transform: [[1.0");
    assert!(
        located
            .iter()
            .any(|l| l.starts_with(&format!("hand.yaml:{tmax_line}:"))
                && l.contains("world.launch.rays[1].tmax: tmax below tmin")),
        "{located:#?}"
    );
    assert!(
        located
            .iter()
            .any(|l| l.starts_with(&format!("hand.yaml:{inst_line}:"))
                && l.contains(
                    "world.launch.scene.instances[0].transform: the 3x3 part is singular"
                )),
        "{located:#?}"
    );
    assert!(why.to_string().contains("scene is undefined"), "{why}");
}
