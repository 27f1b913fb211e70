//! Values.

use super::*;

/// Unsigned integers that break index, offset and size arithmetic.
pub(crate) fn adversarial_u64() -> BoxedStrategy<u64> {
    let m = MAX_ACCESSOR_VALUES;
    prop_oneof![
        // Small: mostly valid indices and counts, some just past the end of an array.
        5 => 0u64..=72,
        3 => select(vec![
            96, 127, 128, 255, 256, 4095, 4096, 32767, 65535, 65536, 1 << 20, 1 << 24,
            m / 16, m / 16 + 1, m / 9, m / 4, m / 3, m / 3 + 1, m / 2, m, m + 1,
            (1 << 31) - 1, 1 << 31, u64::from(u32::MAX) - 3, u64::from(u32::MAX), 1 << 32,
            1 << 53, (1 << 53) + 1, i64::MAX as u64, u64::MAX - 7, u64::MAX,
        ]),
        1 => any::<u32>().prop_map(u64::from),
        1 => any::<u64>(),
    ]
    .boxed()
}

pub(crate) fn int_value() -> BoxedStrategy<Value> {
    prop_oneof![
        8 => adversarial_u64().prop_map(Value::from),
        1 => select(vec![-1i64, -2, -3, -4, -32768, i64::from(i32::MIN), i64::MIN]).prop_map(Value::from),
    ]
    .boxed()
}

pub(crate) fn float_value() -> BoxedStrategy<Value> {
    prop_oneof![
        3 => select(vec![
            1e308, -1e308, f64::MAX, f64::MIN, f64::MIN_POSITIVE, 5e-324, -0.0, 0.5, 1.5, -1.5,
            0.999_999, 1e-40, 3.402_823_5e38, 3.5e38, 1e20, 4_294_967_295.5, 9_007_199_254_740_993.0,
            std::f64::consts::PI, 1e-300,
        ])
        .prop_map(Value::from),
        1 => any::<f64>().prop_filter("JSON numbers are finite", |x| x.is_finite()).prop_map(Value::from),
    ]
    .boxed()
}

pub(crate) fn string_value() -> BoxedStrategy<Value> {
    prop_oneof![
        4 => select(vec![
            "", " ", "SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4", "VEC1", "VEC5", "vec3",
            "VEC3 ", "OPAQUE", "MASK", "BLEND", "perspective", "orthographic", "point", "spot",
            "directional", "2.0", "1.0", "0", "-1", "4294967296", "1e308", "NaN", "null",
            "a\nb", "line one\nline two\r\nthree", "\t\n\u{b}\u{c}\r", "\u{0}", "\u{85}\u{2028}x",
            "é日本", "\u{1F600}", "../../../../../../../../etc/passwd", "%", "%00", "\\n",
        ])
        .prop_map(Value::from),
        1 => "[a-z_\n]{0,12}".prop_map(Value::from),
        1 => (1usize..3000).prop_map(|n| Value::from("x".repeat(n))),
    ]
    .boxed()
}

/// `[[[...]]]` nested `depth` deep (serde_json refuses more than 128 levels).
pub(crate) fn deep_array(depth: usize) -> Value {
    let mut v = json!(0);
    for _ in 0..depth {
        v = Value::Array(vec![v]);
    }
    v
}

pub(crate) fn leaf_value() -> BoxedStrategy<Value> {
    prop_oneof![
        6 => int_value(),
        2 => float_value(),
        2 => string_value(),
        1 => any::<bool>().prop_map(Value::Bool),
        1 => Just(Value::Null),
        1 => Just(json!([])),
        1 => Just(json!({})),
        1 => prop_oneof![1usize..=8, 120usize..=200].prop_map(deep_array),
    ]
    .boxed()
}

/// Any value: a leaf, or small arrays and objects of them.
pub(crate) fn any_value() -> BoxedStrategy<Value> {
    let keys = select(vec![
        "bufferView",
        "byteOffset",
        "count",
        "componentType",
        "type",
        "indices",
        "values",
        "attributes",
        "POSITION",
        "mesh",
        "children",
        "uri",
        "byteLength",
        "light",
        "lights",
        "index",
        "extensions",
        "x",
    ]);
    leaf_value()
        .prop_recursive(3, 24, 6, move |inner| {
            prop_oneof![
                prop::collection::vec(inner.clone(), 0..6).prop_map(Value::Array),
                prop::collection::btree_map(keys.clone().prop_map(str::to_owned), inner, 0..4)
                    .prop_map(|m| Value::Object(m.into_iter().collect())),
            ]
        })
        .boxed()
}

/// What a field holds, to generate values of its own kind.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Class {
    Index,
    IndexList,
    Size,
    Stride,
    Component,
    AccessorType,
    Mode,
    Bool,
    Number,
    Numbers(usize),
    Str,
    Uri,
    Sparse,
    SparseRef,
    Extensions,
    ExtensionNames,
    TextureInfo,
    Attributes,
    Array,
    Object,
}

pub(crate) fn index_value() -> BoxedStrategy<Value> {
    prop_oneof![6 => (0u64..=72).prop_map(Value::from), 3 => int_value(), 1 => leaf_value()].boxed()
}

pub(crate) fn index_list() -> BoxedStrategy<Value> {
    prop::collection::vec(
        prop_oneof![8 => (0u64..=40).prop_map(Value::from), 1 => int_value(), 1 => leaf_value()],
        0..8,
    )
    .prop_map(Value::Array)
    .boxed()
}

pub(crate) fn numbers(n: usize) -> BoxedStrategy<Value> {
    let num = prop_oneof![4 => (-4i32..=4).prop_map(Value::from), 4 => float_value(), 1 => int_value(), 1 => leaf_value()];
    prop::collection::vec(num, 0..=n + 2).prop_map(Value::Array).boxed()
}

pub(crate) fn sparse_ref(indices: bool) -> BoxedStrategy<Value> {
    let comp =
        prop_oneof![4 => select(vec![5121u64, 5123, 5125]).prop_map(Value::from), 1 => component_value()];
    (index_value(), prop_oneof![3 => Just(json!(0)), 1 => size_value()], comp, any::<bool>())
        .prop_map(move |(view, offset, comp, with_offset)| {
            let mut o = Map::new();
            o.insert("bufferView".into(), view);
            if with_offset {
                o.insert("byteOffset".into(), offset);
            }
            if indices {
                o.insert("componentType".into(), comp);
            }
            Value::Object(o)
        })
        .boxed()
}

pub(crate) fn sparse_value() -> BoxedStrategy<Value> {
    (
        prop_oneof![3 => (0u64..=64).prop_map(Value::from), 1 => size_value()],
        sparse_ref(true),
        sparse_ref(false),
    )
        .prop_map(|(count, indices, values)| json!({"count": count, "indices": indices, "values": values}))
        .boxed()
}

pub(crate) fn size_value() -> BoxedStrategy<Value> {
    prop_oneof![
        4 => adversarial_u64().prop_map(Value::from),
        2 => (0u64..=4096).prop_map(|x| Value::from(x * 4)),
        1 => int_value(),
        1 => leaf_value(),
    ]
    .boxed()
}

pub(crate) fn component_value() -> BoxedStrategy<Value> {
    prop_oneof![
        4 => select(vec![5120u64, 5121, 5122, 5123, 5124, 5125, 5126, 5130, 5119, 0, 5121 + (1 << 32)]).prop_map(Value::from),
        1 => leaf_value(),
    ]
    .boxed()
}

pub(crate) fn extension_names() -> BoxedStrategy<Value> {
    let name = prop_oneof![
        4 => select(vec![
            "KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_texture_transform",
            "KHR_mesh_quantization", "EXT_mesh_gpu_instancing", "KHR_draco_mesh_compression",
            "EXT_meshopt_compression", "KHR_materials_specular", "MSFT_texture_dds", "KHR_texture_basisu",
            "EXT_texture_webp", "VENDOR_unknown", "", "a\nb",
        ])
        .prop_map(Value::from),
        1 => leaf_value(),
    ];
    prop_oneof![5 => prop::collection::vec(name, 0..5).prop_map(Value::Array), 1 => leaf_value()].boxed()
}

pub(crate) fn extensions_value() -> BoxedStrategy<Value> {
    let light =
        (select(vec!["point", "spot", "directional", "area", ""]), numbers(3), float_value(), float_value())
            .prop_map(|(t, color, intensity, cone)| {
                json!({"type": t, "color": color, "intensity": intensity, "range": 1, "name": "l\nx",
                   "spot": {"innerConeAngle": cone, "outerConeAngle": 0.5}})
            });
    prop_oneof![
        2 => index_value().prop_map(|l| json!({"KHR_lights_punctual": {"light": l}})),
        2 => prop::collection::vec(light, 0..3).prop_map(|l| json!({"KHR_lights_punctual": {"lights": l}})),
        3 => (index_value(), index_value(), index_value(), 0u8..8).prop_map(|(t, r, s, mask)| {
            let mut a = Map::new();
            for (bit, (k, v)) in [("TRANSLATION", t), ("ROTATION", r), ("SCALE", s)].into_iter().enumerate() {
                if mask & (1 << bit) != 0 {
                    a.insert(k.into(), v);
                }
            }
            json!({"EXT_mesh_gpu_instancing": {"attributes": a}})
        }),
        2 => (numbers(2), float_value(), numbers(2), index_value()).prop_map(|(o, r, s, t)| {
            json!({"KHR_texture_transform": {"offset": o, "rotation": r, "scale": s, "texCoord": t}})
        }),
        1 => float_value().prop_map(|s| json!({"KHR_materials_emissive_strength": {"emissiveStrength": s}})),
        1 => (index_value(), index_value()).prop_map(|(v, a)| {
            json!({"KHR_draco_mesh_compression": {"bufferView": v, "attributes": {"POSITION": a}}})
        }),
        1 => any_value(),
    ]
    .boxed()
}

pub(crate) fn uri_value() -> BoxedStrategy<Value> {
    select(vec![
        "data:application/octet-stream;base64,",
        "data:application/octet-stream;base64,AAAA",
        "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA",
        "data:application/octet-stream;base64,!!!!",
        "data:application/octet-stream;base64,A",
        "data:application/octet-stream;base64,====",
        "data:application/octet-stream;base64,QUJD\nREVG",
        "data:application/octet-stream,%00%ff%zz%",
        "data:",
        "data:,",
        "data:;base64",
        "data:image/png;base64,iVBORw0KGgo=",
        "data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAQAAAC1HAwCAAAAC0lEQVR42mNkYAAAA",
        TINY_PNG,
        "BreakfastRoom.bin",
        "marble.jpg",
        "tiles.png",
        "missing.bin",
        "",
        "%",
        "%2e%2e/%2e%2e/nope",
        ".",
        "..",
        "http://example.invalid/a.bin",
        "file:///dev/zero",
        "/dev/zero",
        "../../../../../../../../../../dev/zero",
        "/dev/null",
        "/proc/self/status",
    ])
    .prop_map(Value::from)
    .boxed()
}

pub(crate) fn texture_info() -> BoxedStrategy<Value> {
    (index_value(), prop::option::of(index_value()), prop::option::of(extensions_value()))
        .prop_map(|(index, tc, ext)| {
            let mut o = Map::new();
            o.insert("index".into(), index);
            if let Some(tc) = tc {
                o.insert("texCoord".into(), tc);
            }
            if let Some(ext) = ext {
                o.insert("extensions".into(), ext);
            }
            Value::Object(o)
        })
        .boxed()
}

pub(crate) fn attributes_value() -> BoxedStrategy<Value> {
    let name = select(vec![
        "POSITION",
        "NORMAL",
        "TANGENT",
        "TEXCOORD_0",
        "TEXCOORD_1",
        "TEXCOORD_7",
        "COLOR_0",
        "JOINTS_0",
    ]);
    prop::collection::btree_map(name.prop_map(str::to_owned), index_value(), 0..5)
        .prop_map(|m| Value::Object(m.into_iter().collect()))
        .boxed()
}

/// A value for a field of class `c`: mostly of its kind, sometimes anything at all.
pub(crate) fn value_of(c: Class) -> BoxedStrategy<Value> {
    let specific = match c {
        Class::Index => index_value(),
        Class::IndexList => index_list(),
        Class::Size => size_value(),
        Class::Stride => select(vec![
            0u64,
            1,
            2,
            3,
            4,
            5,
            8,
            11,
            12,
            16,
            20,
            24,
            31,
            32,
            33,
            64,
            252,
            255,
            256,
            1 << 20,
            u64::from(u32::MAX),
        ])
        .prop_map(Value::from)
        .boxed(),
        Class::Component => component_value(),
        Class::AccessorType => string_value(),
        Class::Mode => prop_oneof![(0u64..=8).prop_map(Value::from), int_value()].boxed(),
        Class::Bool => prop_oneof![any::<bool>().prop_map(Value::Bool), leaf_value()].boxed(),
        Class::Number => prop_oneof![float_value(), int_value()].boxed(),
        Class::Numbers(n) => numbers(n),
        Class::Str => string_value(),
        Class::Uri => uri_value(),
        Class::Sparse => sparse_value(),
        Class::SparseRef => sparse_ref(true),
        Class::Extensions => extensions_value(),
        Class::ExtensionNames => extension_names(),
        Class::TextureInfo => texture_info(),
        Class::Attributes => attributes_value(),
        Class::Array => prop_oneof![
            Just(json!([])),
            prop::collection::vec(leaf_value(), 1..4).prop_map(Value::Array),
            any_value()
        ]
        .boxed(),
        Class::Object => prop_oneof![Just(json!({})), any_value()].boxed(),
    };
    prop_oneof![5 => specific, 1 => any_value()].boxed()
}
