//! Mutations.

use super::*;
use lightvol_scene::load::gltf::base64_encode as base64;

/// How a number is nudged.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Nudge {
    Add(i64),
    Mul(i64),
    Negate,
    Stringify,
    PlusHalf,
}

/// How a `data:` URI is damaged.
#[derive(Clone, Debug)]
pub(crate) enum UriDamage {
    /// Cut the URI at this fraction of its length.
    Truncate(Index),
    /// Put this character at this position.
    Poke(Index, char),
    /// Drop the `,` between header and data.
    DropComma,
    /// Drop the `;base64` marker (the payload is then read as percent-encoded text).
    DropBase64,
    /// Append the payload again (more bytes than `byteLength`).
    Double,
}

/// One structural change to a glTF JSON document. Indices pick among the document's
/// current paths (or objects of the right kind) when the mutation is applied.
#[derive(Clone, Debug)]
pub(crate) enum JsonMutation {
    /// Set `FIELDS[field]` on an object of one of its kinds.
    SetField { field: usize, target: Index, value: Value },
    /// Replace the value at any path.
    Replace { at: Index, value: Value },
    /// Delete an object key or array element.
    Delete { at: Index },
    /// Nudge a number.
    Nudge { at: Index, how: Nudge },
    /// Copy the value at one path over another.
    Copy { from: Index, to: Index },
    /// Make `child` a child of `parent` (cycles, self-loops, shared children).
    Link { parent: Index, child: Index },
    /// Append `times` copies of an array's element (primitives and nodes that share data).
    Duplicate { array: Index, element: Index, times: usize },
    /// Remove an accessor's buffer view and give it `count` elements (zeros nobody stored).
    Viewless { accessor: Index, count: u64 },
    /// Damage a `data:` URI.
    DataUri { target: Index, how: UriDamage },
}

pub(crate) fn json_mutation() -> BoxedStrategy<JsonMutation> {
    let m = MAX_ACCESSOR_VALUES;
    let set_field = (0..FIELDS.len())
        .prop_flat_map(|f| (Just(f), any::<Index>(), value_of(FIELDS[f].2)))
        .prop_map(|(field, target, value)| JsonMutation::SetField { field, target, value });
    let nudge = prop_oneof![
        4 => select(vec![-2i64, -1, 1, 2, 3, 4, 7, 8, 12, 16, 32, 1 << 16, 1 << 31]).prop_map(Nudge::Add),
        2 => select(vec![2i64, 3, 4, 1000, 1 << 20, 1 << 32]).prop_map(Nudge::Mul),
        1 => Just(Nudge::Negate),
        1 => Just(Nudge::Stringify),
        1 => Just(Nudge::PlusHalf),
    ];
    let damage = prop_oneof![
        3 => any::<Index>().prop_map(UriDamage::Truncate),
        3 => (any::<Index>(), select(vec!['!', '*', '\n', ' ', '=', '-', '_', '%', 'é', '\u{0}', ','])).prop_map(|(i, c)| UriDamage::Poke(i, c)),
        1 => Just(UriDamage::DropComma),
        1 => Just(UriDamage::DropBase64),
        1 => Just(UriDamage::Double),
    ];
    prop_oneof![
        8 => set_field,
        3 => (any::<Index>(), any_value()).prop_map(|(at, value)| JsonMutation::Replace { at, value }),
        2 => any::<Index>().prop_map(|at| JsonMutation::Delete { at }),
        3 => (any::<Index>(), nudge).prop_map(|(at, how)| JsonMutation::Nudge { at, how }),
        1 => (any::<Index>(), any::<Index>()).prop_map(|(from, to)| JsonMutation::Copy { from, to }),
        2 => (any::<Index>(), any::<Index>()).prop_map(|(parent, child)| JsonMutation::Link { parent, child }),
        1 => (any::<Index>(), any::<Index>(), prop_oneof![3 => Just(1usize), 1 => 2usize..=64])
            .prop_map(|(array, element, times)| JsonMutation::Duplicate { array, element, times }),
        1 => (any::<Index>(), select(vec![3, 1 << 16, 1 << 20, 1 << 24, m / 16, m / 4, m / 3, m / 3 + 1, m, u64::from(u32::MAX)]))
            .prop_map(|(accessor, count)| JsonMutation::Viewless { accessor, count }),
        2 => (any::<Index>(), damage).prop_map(|(target, how)| JsonMutation::DataUri { target, how }),
    ]
    .boxed()
}

pub(crate) fn pick<'a, T>(items: &'a [T], i: &Index) -> Option<&'a T> {
    (!items.is_empty()).then(|| &items[i.index(items.len())])
}

pub(crate) fn nudged(v: &Value, how: Nudge) -> Option<Value> {
    let x = v.as_f64()?;
    let int = v.as_i64().map(i128::from).or(v.as_u64().map(i128::from));
    let from_int = |n: i128| {
        u64::try_from(n)
            .map(Value::from)
            .or_else(|_| i64::try_from(n).map(Value::from))
            .unwrap_or_else(|_| Value::from(n as f64))
    };
    Some(match (how, int) {
        (Nudge::Add(d), Some(n)) => from_int(n + i128::from(d)),
        (Nudge::Add(d), None) => Value::from(x + d as f64),
        (Nudge::Mul(k), Some(n)) => from_int(n.saturating_mul(i128::from(k))),
        (Nudge::Mul(k), None) => Value::from(x * k as f64),
        (Nudge::Negate, Some(n)) => from_int(-n),
        (Nudge::Negate, None) => Value::from(-x),
        (Nudge::Stringify, _) => Value::from(v.to_string()),
        (Nudge::PlusHalf, _) => Value::from(x + 0.5),
    })
}

/// The `data:` URI of `bin`.
pub(crate) fn data_uri(bin: &[u8]) -> String {
    format!("data:application/octet-stream;base64,{}", base64(bin))
}

pub(crate) fn damaged(uri: &str, how: &UriDamage) -> String {
    let chars: Vec<char> = uri.chars().collect();
    match how {
        UriDamage::Truncate(i) => chars[..i.index(chars.len() + 1)].iter().collect(),
        UriDamage::Poke(i, c) => {
            let mut chars = chars;
            if !chars.is_empty() {
                let at = i.index(chars.len());
                chars[at] = *c;
            }
            chars.into_iter().collect()
        }
        UriDamage::DropComma => uri.replacen(',', "", 1),
        UriDamage::DropBase64 => uri.replacen(";base64", "", 1),
        UriDamage::Double => {
            let payload = uri.split_once(',').map_or("", |(_, p)| p);
            format!("{uri}{payload}")
        }
    }
}

pub(crate) fn apply(doc: &mut Value, bin: &[u8], m: &JsonMutation) {
    let paths = all_paths(doc);
    let objects_of = |kinds: &[Kind]| -> Vec<JsonPath> {
        paths
            .iter()
            .filter(|p| {
                kind_of(p).is_some_and(|k| kinds.contains(&k)) && get(doc, p).is_some_and(Value::is_object)
            })
            .cloned()
            .collect()
    };
    let set = |doc: &mut Value, path: &[Seg], value: Value| {
        if let Some(slot) = get_mut(doc, path) {
            *slot = value;
        }
    };
    match m {
        JsonMutation::SetField { field, target, value } => {
            let (name, kinds, _) = FIELDS[*field];
            let mut targets = objects_of(kinds);
            if targets.is_empty() {
                // No such object (a sampler, a sparse block): any object gets the field.
                targets =
                    paths.iter().filter(|p| get(doc, p).is_some_and(Value::is_object)).cloned().collect();
            }
            if let Some(p) = pick(&targets, target)
                && let Some(Value::Object(o)) = get_mut(doc, p)
            {
                o.insert(name.to_owned(), value.clone());
            }
        }
        JsonMutation::Replace { at, value } => {
            if let Some(p) = pick(&paths, at) {
                set(doc, &p.clone(), value.clone());
            }
        }
        JsonMutation::Delete { at } => {
            let Some((last, parent)) = pick(&paths[1..], at).and_then(|p| p.split_last()) else { return };
            match (get_mut(doc, parent), last.clone()) {
                (Some(Value::Object(o)), Seg::Key(k)) => {
                    o.remove(&k);
                }
                (Some(Value::Array(a)), Seg::At(i)) => {
                    a.remove(i);
                }
                _ => {}
            }
        }
        JsonMutation::Nudge { at, how } => {
            let numbers: Vec<&JsonPath> =
                paths.iter().filter(|p| get(doc, p).is_some_and(Value::is_number)).collect();
            if let Some(&p) = pick(&numbers, at)
                && let Some(v) = get(doc, p).and_then(|v| nudged(v, *how))
            {
                set(doc, &p.clone(), v);
            }
        }
        JsonMutation::Copy { from, to } => {
            if let (Some(f), Some(t)) = (pick(&paths, from), pick(&paths, to))
                && let Some(v) = get(doc, f).cloned()
            {
                set(doc, &t.clone(), v);
            }
        }
        JsonMutation::Link { parent, child } => {
            let n = doc.get("nodes").and_then(Value::as_array).map_or(0, Vec::len);
            if n == 0 {
                return;
            }
            let (p, c) = (parent.index(n), child.index(n));
            if let Some(node) = doc["nodes"][p].as_object_mut() {
                let children = node.entry("children").or_insert_with(|| json!([]));
                if let Some(a) = children.as_array_mut() {
                    a.push(json!(c));
                } else {
                    *children = json!([c]);
                }
            }
        }
        JsonMutation::Duplicate { array, element, times } => {
            let arrays: Vec<&JsonPath> = paths
                .iter()
                .filter(|p| get(doc, p).and_then(Value::as_array).is_some_and(|a| !a.is_empty()))
                .collect();
            if let Some(&p) = pick(&arrays, array)
                && let Some(Value::Array(a)) = get_mut(doc, p)
            {
                let e = a[element.index(a.len())].clone();
                a.extend(std::iter::repeat_n(e, *times));
            }
        }
        JsonMutation::Viewless { accessor, count } => {
            let accessors = objects_of(&[Kind::Accessor]);
            if let Some(p) = pick(&accessors, accessor)
                && let Some(Value::Object(o)) = get_mut(doc, p)
            {
                o.remove("bufferView");
                o.insert("count".into(), json!(count));
            }
        }
        JsonMutation::DataUri { target, how } => {
            let uris: Vec<&JsonPath> = paths
                .iter()
                .filter(|p| {
                    get(doc, p)
                        .and_then(Value::as_str)
                        .is_some_and(|s| s == BIN_PLACEHOLDER || s.starts_with("data:"))
                })
                .collect();
            if let Some(&p) = pick(&uris, target) {
                let uri = match get(doc, p).and_then(Value::as_str) {
                    Some(BIN_PLACEHOLDER) => data_uri(bin),
                    Some(s) => s.to_owned(),
                    None => return,
                };
                set(doc, &p.clone(), Value::from(damaged(&uri, how)));
            }
        }
    }
}

/// A u32 of the binary buffer overwritten, or bytes cut from its end.
#[derive(Clone, Debug)]
pub(crate) enum BinMutation {
    Word { at: Index, value: u32 },
    Flip { at: Index, xor: u8 },
    Truncate { at: Index },
}

pub(crate) fn bin_mutation() -> BoxedStrategy<BinMutation> {
    let word = prop_oneof![
        3 => select(vec![
            0x7FC0_0000u32, 0xFFC0_0000, 0x7F80_0000, 0xFF80_0000, 0x7F7F_FFFF, 0x0000_0001, 0,
            u32::MAX, 0x8000_0000, 0x0001_0000, 0xFFFF, 5000, 100_000,
        ]),
        1 => any::<u32>(),
    ];
    prop_oneof![
        6 => (any::<Index>(), word).prop_map(|(at, value)| BinMutation::Word { at, value }),
        3 => (any::<Index>(), 1u8..=255).prop_map(|(at, xor)| BinMutation::Flip { at, xor }),
        1 => any::<Index>().prop_map(|at| BinMutation::Truncate { at }),
    ]
    .boxed()
}

pub(crate) fn apply_bin(bin: &mut Vec<u8>, m: &BinMutation) {
    if bin.is_empty() {
        return;
    }
    match m {
        BinMutation::Word { at, value } => {
            let words = bin.len() / 4;
            if words > 0 {
                let o = 4 * at.index(words);
                bin[o..o + 4].copy_from_slice(&value.to_le_bytes());
            }
        }
        BinMutation::Flip { at, xor } => {
            let i = at.index(bin.len());
            bin[i] ^= xor;
        }
        BinMutation::Truncate { at } => bin.truncate(at.index(bin.len())),
    }
}

/// A change to the serialized JSON text.
#[derive(Clone, Debug)]
pub(crate) enum TextMutation {
    /// Replace a number token with this text.
    Number { which: Index, with: &'static str },
    /// Cut the text.
    Truncate { at: Index },
    /// Insert a byte.
    Insert { at: Index, byte: u8 },
}

pub(crate) fn text_mutation() -> BoxedStrategy<TextMutation> {
    let with = select(vec![
        "1e999",
        "-1e999",
        "NaN",
        "Infinity",
        "-Infinity",
        "1e-999",
        "00",
        "-",
        "0x10",
        "1.",
        ".5",
        "+1",
        "18446744073709551616",
        "-9223372036854775809",
        "1E400",
        "-0",
    ]);
    prop_oneof![
        6 => (any::<Index>(), with).prop_map(|(which, with)| TextMutation::Number { which, with }),
        1 => any::<Index>().prop_map(|at| TextMutation::Truncate { at }),
        1 => (any::<Index>(), any::<u8>()).prop_map(|(at, byte)| TextMutation::Insert { at, byte }),
    ]
    .boxed()
}

pub(crate) fn apply_text(text: &mut Vec<u8>, m: &TextMutation) {
    match m {
        TextMutation::Number { which, with } => {
            let mut spans = Vec::new();
            let mut i = 0;
            while i < text.len() {
                let starts = (text[i].is_ascii_digit() || text[i] == b'-')
                    && i > 0
                    && matches!(text[i - 1], b':' | b',' | b'[' | b' ');
                if starts {
                    let s = i;
                    while i < text.len() && matches!(text[i], b'0'..=b'9' | b'-' | b'+' | b'.' | b'e' | b'E')
                    {
                        i += 1;
                    }
                    spans.push(s..i);
                } else {
                    i += 1;
                }
            }
            if let Some(r) = pick(&spans, which).cloned() {
                text.splice(r, with.bytes());
            }
        }
        TextMutation::Truncate { at } => text.truncate(at.index(text.len() + 1)),
        TextMutation::Insert { at, byte } => text.insert(at.index(text.len() + 1), *byte),
    }
}

/// Replaces [`BIN_PLACEHOLDER`] strings by the buffer's `data:` URI.
pub(crate) fn fill_placeholder(v: &mut Value, bin: &[u8]) {
    match v {
        Value::String(s) if s == BIN_PLACEHOLDER => *s = data_uri(bin),
        Value::Array(a) => a.iter_mut().for_each(|c| fill_placeholder(c, bin)),
        Value::Object(o) => o.values_mut().for_each(|c| fill_placeholder(c, bin)),
        _ => {}
    }
}

/// The mutated JSON text and binary buffer of a document.
pub(crate) fn mutated(
    f: &Fixture,
    json: &[JsonMutation],
    bin: &[BinMutation],
    text: Option<&TextMutation>,
) -> (Vec<u8>, Vec<u8>) {
    let mut b = f.bin.clone();
    for m in bin {
        apply_bin(&mut b, m);
    }
    let mut doc = f.json.clone();
    for m in json {
        apply(&mut doc, &b, m);
    }
    fill_placeholder(&mut doc, &b);
    let mut t = serde_json::to_vec(&doc).expect("a Value serializes");
    if let Some(m) = text {
        apply_text(&mut t, m);
    }
    (t, b)
}

/// A `.gltf` case.
#[derive(Clone, Debug)]
pub(crate) struct JsonCase {
    pub(crate) json: Vec<JsonMutation>,
    pub(crate) bin: Vec<BinMutation>,
    pub(crate) text: Option<TextMutation>,
}

pub(crate) fn json_case() -> impl Strategy<Value = JsonCase> {
    (
        prop::collection::vec(json_mutation(), 1..=MAX_MUTATIONS),
        prop_oneof![3 => Just(Vec::new()), 1 => prop::collection::vec(bin_mutation(), 1..=2)],
        prop_oneof![7 => Just(None), 1 => text_mutation().prop_map(Some)],
    )
        .prop_map(|(json, bin, text)| JsonCase { json, bin, text })
}
