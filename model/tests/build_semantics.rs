//! The meaning of a build: hand examples (index + firstVertex + transform, inactive primitives,
//! PrimitiveId from the range start, arrays of pointers) and the metamorphic relation
//! "indirect with ranges R ≡ direct with R" over many stride/offset layouts of the same records.

use model::accel::call::{BuildFlags, GeometryFlags};
use model::accel::world::{identity, InstanceRecord, InstanceReference};
use model::accel::*;
use model::call::Address;
use model::flags::BufferUsage;

fn addr(b: &str, o: u64) -> Address {
    Address::InBuffer {
        buffer: b.into(),
        offset: o,
    }
}

fn buffer(name: &str, size: u64, contents: Vec<BuildContents>) -> BuildBuffer {
    BuildBuffer {
        name: name.into(),
        size,
        usage: BufferUsage::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR
            | BufferUsage::INDIRECT_BUFFER_BIT,
        flags: Default::default(),
        memory: Default::default(),
        contents,
    }
}

fn world(buffers: Vec<BuildBuffer>) -> BuildWorld {
    BuildWorld {
        device: Default::default(),
        buffers,
        structures: vec![],
        command_buffer: Default::default(),
        sizes: vec![],
    }
}

fn info(geometries: Vec<GeometryData>) -> BuildGeometryInfo {
    BuildGeometryInfo {
        ty: AsType::BottomLevel,
        flags: BuildFlags(0),
        mode: BuildMode::Build,
        src: None,
        dst: Some("dst".into()),
        geometries: geometries
            .into_iter()
            .map(|data| Geometry {
                flags: GeometryFlags(0),
                data,
            })
            .collect(),
        geometries_by_pointer: false,
        scratch: Address::NULL,
    }
}

fn indexed_triangles() -> (BuildWorld, BuildGeometryInfo) {
    // Vertices 0..6 along x; indices at byte 96; a translation by (10, 0, 0) at byte 160 + 16.
    let verts: Vec<f32> = (0..6).flat_map(|k| [k as f32, 0.0, 0.0]).collect();
    let mut m = identity();
    m[3] = 10.0;
    let w = world(vec![buffer(
        "in",
        256,
        vec![
            BuildContents::Floats {
                offset: 0,
                values: verts,
            },
            BuildContents::U16s {
                offset: 96,
                values: vec![0, 1, 2, 2, 1, 0],
            },
            BuildContents::Floats {
                offset: 176,
                values: m.to_vec(),
            },
        ],
    )]);
    let i = info(vec![GeometryData::Triangles {
        vertex_format: VertexFormat::R32g32b32Sfloat,
        vertex_data: addr("in", 0),
        vertex_stride: 12,
        max_vertex: 5,
        index_type: IndexType::Uint16,
        index_data: addr("in", 96),
        transform_data: addr("in", 160),
        motion_vertex_data: None,
        opacity_micromap: None,
    }]);
    (w, i)
}

#[test]
fn indexed_triangles_apply_offset_first_vertex_and_transform() {
    let (w, i) = indexed_triangles();
    let mem = w.memory();
    // primitiveOffset 6 skips the first triangle's indices; firstVertex 3 adds to each index.
    let r = [RangeInfo {
        primitive_count: 1,
        primitive_offset: 6,
        first_vertex: 3,
        transform_offset: 16,
    }];
    let p = build_primitives(&mem, &i, &r).unwrap();
    assert_eq!(p.len(), 1);
    assert_eq!(
        p[0].primitive, 0,
        "PrimitiveId counts from the start of the range"
    );
    assert_eq!(
        p[0].shape,
        Shape::Triangle([[15.0, 0.0, 0.0], [14.0, 0.0, 0.0], [13.0, 0.0, 0.0]])
    );
    assert!(p[0].active);
}

#[test]
fn nan_x_makes_a_triangle_inactive_and_it_keeps_its_primitive_id() {
    let w = world(vec![buffer(
        "in",
        128,
        vec![BuildContents::Floats {
            offset: 0,
            values: vec![
                0.,
                0.,
                0.,
                1.,
                0.,
                0.,
                0.,
                1.,
                0.,
                f32::NAN,
                0.,
                0.,
                1.,
                0.,
                0.,
                0.,
                1.,
                0.,
            ],
        }],
    )]);
    let i = info(vec![GeometryData::Triangles {
        vertex_format: VertexFormat::R32g32b32Sfloat,
        vertex_data: addr("in", 0),
        vertex_stride: 12,
        max_vertex: 5,
        index_type: IndexType::None,
        index_data: Address::NULL,
        transform_data: Address::NULL,
        motion_vertex_data: None,
        opacity_micromap: None,
    }]);
    let p = build_primitives(
        &w.memory(),
        &i,
        &[RangeInfo {
            primitive_count: 2,
            ..Default::default()
        }],
    )
    .unwrap();
    assert_eq!(
        p.iter()
            .map(|p| (p.primitive, p.active))
            .collect::<Vec<_>>(),
        vec![(0, true), (1, false)]
    );
}

#[test]
fn aabbs_and_instances_through_pointers() {
    let rec = |r: InstanceReference| InstanceRecord {
        transform: identity(),
        custom_index: 7,
        mask: 1,
        sbt_offset: 0,
        flags: 0,
        reference: r,
    };
    let mut w = world(vec![buffer(
        "in",
        512,
        vec![
            BuildContents::Floats {
                offset: 8,
                values: vec![f32::NAN, 0., 0., 1., 1., 1., 2., 2., 2., 3., 3., 3.],
            },
            BuildContents::Instances {
                offset: 64,
                instances: vec![
                    rec(InstanceReference::Structure("blas".into())),
                    rec(InstanceReference::Null),
                ],
            },
            BuildContents::Pointers {
                offset: 256,
                targets: vec![addr("in", 128), addr("in", 64)],
            },
        ],
    )]);
    w.structures.push(AccelerationStructure {
        name: "blas".into(),
        ty: AsType::BottomLevel,
        buffer: "in".into(),
        offset: 0,
        size: 0,
        last_build: None,
    });
    let mem = w.memory();
    let a = info(vec![GeometryData::Aabbs {
        data: addr("in", 0),
        stride: 24,
    }]);
    let p = build_primitives(
        &mem,
        &a,
        &[RangeInfo {
            primitive_count: 2,
            primitive_offset: 8,
            ..Default::default()
        }],
    )
    .unwrap();
    assert!(!p[0].active && p[1].active, "NaN minX is inactive");
    let t = info(vec![GeometryData::Instances {
        array_of_pointers: true,
        data: addr("in", 256),
    }]);
    let p = build_primitives(
        &mem,
        &t,
        &[RangeInfo {
            primitive_count: 2,
            ..Default::default()
        }],
    )
    .unwrap();
    assert_eq!(
        p.iter().map(|p| p.active).collect::<Vec<_>>(),
        vec![false, true],
        "pointer 0 names the null-reference record"
    );
}

#[test]
fn reading_past_a_buffer_is_an_error_not_a_guess() {
    let (w, i) = indexed_triangles();
    let r = [RangeInfo {
        primitive_count: 50,
        ..Default::default()
    }];
    assert!(build_primitives(&w.memory(), &i, &r).is_err());
}

/// Indirect with ranges R ≡ direct with R, for every stride and offset of the records.
#[test]
fn indirect_with_ranges_r_is_direct_with_r() {
    let (base, i) = indexed_triangles();
    let i2 = BuildGeometryInfo {
        geometries: vec![i.geometries[0].clone(), i.geometries[0].clone()],
        ..i
    };
    let ranges = vec![
        RangeInfo {
            primitive_count: 2,
            primitive_offset: 0,
            first_vertex: 0,
            transform_offset: 0,
        },
        RangeInfo {
            primitive_count: 1,
            primitive_offset: 6,
            first_vertex: 3,
            transform_offset: 16,
        },
    ];
    let direct = direct_build(
        &base,
        std::slice::from_ref(&i2),
        std::slice::from_ref(&ranges),
    )
    .unwrap();
    for stride in (16..=64).step_by(4) {
        for off in (0..=32).step_by(4) {
            let mut w = base.clone();
            // Junk between the records must not matter.
            w.buffers.push(buffer(
                "ind",
                512,
                vec![
                    BuildContents::U32s {
                        offset: 0,
                        values: vec![0xdead_beef; 128],
                    },
                    BuildContents::Ranges {
                        offset: off,
                        stride,
                        ranges: ranges.clone(),
                    },
                ],
            ));
            let call = BuildIndirect {
                infos: vec![i2.clone()],
                indirect_addresses: vec![addr("ind", off)],
                indirect_strides: vec![stride as u32],
                max_primitive_counts: vec![vec![2, 1]],
            };
            assert_eq!(
                indirect_build(&w, &call).unwrap(),
                direct,
                "stride {stride}, offset {off}"
            );
        }
    }
}
