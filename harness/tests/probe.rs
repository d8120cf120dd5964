//! The probe on real lavapipe, and a clear error for a driver that is not there.

use harness::{probe, Driver, HarnessError};

#[test]
fn lavapipe_profile_reports_the_ray_tracing_limits() {
    let p = probe(Driver::Lavapipe).expect("lavapipe is installed by scripts/setup.sh");
    assert!(p.has_extension("VK_KHR_ray_tracing_pipeline"));
    assert!(p.has_feature(
        "VkPhysicalDeviceRayTracingPipelineFeaturesKHR::rayTracingPipelineTraceRaysIndirect"
    ));
    assert_eq!(
        p.limit("VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupHandleSize"),
        Some(32)
    );
    assert_eq!(
        p.limit("VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupHandleAlignment"),
        Some(16)
    );
    assert_eq!(
        p.limit("VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupBaseAlignment"),
        Some(32)
    );
    assert!(
        p.limit("VkPhysicalDeviceLimits::maxComputeWorkGroupCount[0]")
            .unwrap_or(0)
            >= 65535
    );
    if std::env::var_os("RTCONF_WRITE_PROFILE").is_some() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../profiles/lavapipe.json");
        std::fs::write(path, p.to_profiles_json()).expect("profiles/ is writable");
    }
    let again =
        model::profile::DeviceProfile::from_profiles_json("lavapipe", &p.to_profiles_json())
            .unwrap();
    assert_eq!(again.limit("shaderGroupHandleSize"), Some(32));
    assert_eq!(again.extensions, p.extensions);
}

#[test]
fn a_missing_icd_is_a_clear_error_not_a_panic() {
    let err = probe(Driver::Icd("/nonexistent/rtconf_icd.json".into())).unwrap_err();
    assert!(matches!(err, HarnessError::IcdMissing(_)), "{err}");
    let text = err.to_string();
    assert!(
        text.contains("/nonexistent/rtconf_icd.json") && text.contains("bash scripts/setup.sh"),
        "{text}"
    );
}
