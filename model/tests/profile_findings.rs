//! The committed profiles, probed from real drivers, read as usable, and the limits they report
//! outside the specification's requirements are exactly the ones written down here.

use model::required_limits::findings;
use model::DeviceProfile;

fn profile(name: &str) -> DeviceProfile {
    let p =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../profiles/{name}.json"));
    DeviceProfile::from_profiles_json(name, &std::fs::read_to_string(p).unwrap())
        .unwrap_or_else(|e| panic!("{name}: {e}"))
}

#[test]
fn committed_profiles_break_only_the_known_requirements() {
    for (name, known) in [
        // Mesa 25.0.7's lavapipe, which calls itself not conformant: two limits below the minimum.
        (
            "lavapipe",
            vec![
                "the device reports VkPhysicalDeviceRayTracingPipelinePropertiesKHR::maxRayDispatchInvocationCount = 67108864; the specification requires at least 1073741824 (Limit Requirements)",
                "the device reports VkPhysicalDeviceAccelerationStructurePropertiesKHR::maxPrimitiveCount = 16777215; the specification requires from 536870911 to 4294967295 (Limit Requirements)",
            ],
        ),
        ("nvidia-h100", vec![]),
        ("nvidia-h200", vec![]),
    ] {
        let found: Vec<String> = findings(&profile(name)).iter().map(|f| f.to_string()).collect();
        assert_eq!(found, known, "{name}");
    }
}
