//! Meta-test of the rendered scenes: valid and runnable by construction on every profile and trace
//! command, with every family, ray kind and a spread of launch sizes (most small, a few large).

mod common;

use generator::{generate, CaseSpec, GenError};
use model::scene::GeometryData;
use model::CommandId;

#[test]
fn rendered_cases_are_valid_runnable_and_varied() {
    let mut judged = 0;
    for (name, profile) in common::profiles() {
        for command in CommandId::TRACE {
            let spec = CaseSpec::rendered(command);
            let cases = match generate(&profile, &name, common::rules(), &spec, 60, 5) {
                Ok(c) => c,
                Err(GenError::Unsupported(_)) if command.is_nv() => continue,
                Err(e) => panic!("{name} {command:?}: {e}"),
            };
            let (mut camera, mut listed, mut boxes, mut meshes, mut large, mut small) =
                (0, 0, 0, 0, 0, 0);
            for case in &cases {
                let v = common::judge(&profile, case);
                assert!(v.is_valid(), "{}: {:?}", case.name, v.violations);
                case.runnable(&profile)
                    .unwrap_or_else(|e| panic!("{}: {e}", case.name));
                let t = case.as_trace().unwrap();
                let l = &t.world.launch;
                camera += l.camera.is_some() as usize;
                listed += !l.rays.is_empty() as usize;
                for b in &l.scene.bottom_levels {
                    for g in &b.geometries {
                        match &g.data {
                            GeometryData::Aabbs(_) => boxes += 1,
                            GeometryData::Triangles(t) => meshes += t.indices.is_some() as usize,
                        }
                    }
                    if command.is_nv() {
                        assert!(
                            b.geometries.len() == 1
                                || b.geometries
                                    .iter()
                                    .all(|g| matches!(g.data, GeometryData::Triangles(_))),
                            "NV procedural bottom levels hold one geometry"
                        );
                    }
                }
                let ids: u64 = t
                    .call
                    .dimensions(&t.world)
                    .map_or(0, |d| d.iter().map(|&x| x as u64).product());
                large += (ids >= 4096) as usize;
                small += (ids <= 144) as usize;
                judged += 1;
            }
            for (what, n) in [
                ("camera", camera),
                ("ray list", listed),
                ("boxes", boxes),
                ("indexed mesh", meshes),
                ("large launch", large),
            ] {
                assert!(n >= 1, "{name} {command:?}: no case with a {what}");
            }
            assert!(
                small * 2 > cases.len(),
                "{name} {command:?}: most launches are small"
            );
        }
    }
    assert!(judged >= 120, "judged {judged}");
}
