//! The build cases under `cases/build/` parse and judge as they declare on the lavapipe profile.

#[test]
fn committed_build_cases_judge_as_declared() {
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let set = vk_registry::source::load_vuids(std::path::Path::new("/usr/share/vulkan/registry"))
        .unwrap();
    let rules = model::RuleSet::from_vuids(&set);
    let text = std::fs::read_to_string(root.join("profiles/lavapipe.json")).unwrap();
    let profile = model::DeviceProfile::from_profiles_json("lavapipe", &text).unwrap();
    let mut n = 0;
    for e in std::fs::read_dir(root.join("cases/build")).unwrap() {
        let path = e.unwrap().path();
        let c = model::Case::from_yaml(
            &path.display().to_string(),
            &std::fs::read_to_string(&path).unwrap(),
        )
        .unwrap();
        assert!(c.as_accel().is_some(), "{}", path.display());
        let mut got: Vec<String> = model::validate(&rules, &profile, &c)
            .violations
            .into_iter()
            .map(|v| v.vuid)
            .collect();
        got.sort();
        got.dedup();
        assert_eq!(got, c.expected_vuids(), "{}", path.display());
        n += 1;
    }
    assert!(n >= 2);
}
