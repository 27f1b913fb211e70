//! GLB containers.

use super::*;

/// How the chunks are laid out.
#[derive(Clone, Debug)]
pub(crate) enum Layout {
    Standard,
    NoBin,
    BinFirst,
    TwoJson,
    UnknownChunk { first: bool },
    EmptyBin,
    UnpaddedJson,
    Trailing(Vec<u8>),
}

/// A header word of the packed file.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Field {
    Magic,
    Version,
    Length,
    FirstChunkLength,
    FirstChunkType,
    SecondChunkLength,
    SecondChunkType,
}

/// A value for a header word: absolute, or relative to what is there.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Word {
    Abs(u32),
    Rel(i64),
}

/// A change to the packed GLB bytes.
#[derive(Clone, Debug)]
pub(crate) enum ByteMutation {
    Header {
        field: Field,
        value: Word,
    },
    /// Flip bits of a byte in the header (0), the JSON chunk (1), the BIN chunk (2) or anywhere (3).
    Flip {
        region: u8,
        at: Index,
        xor: u8,
    },
    Truncate {
        at: Index,
    },
}

/// A `.glb` case.
#[derive(Clone, Debug)]
pub(crate) struct GlbCase {
    pub(crate) json: Vec<JsonMutation>,
    pub(crate) bin: Vec<BinMutation>,
    pub(crate) text: Option<TextMutation>,
    pub(crate) layout: Layout,
    pub(crate) bytes: Vec<ByteMutation>,
}

pub(crate) fn byte_mutation() -> BoxedStrategy<ByteMutation> {
    let field = select(vec![
        Field::Magic,
        Field::Version,
        Field::Length,
        Field::FirstChunkLength,
        Field::FirstChunkType,
        Field::SecondChunkLength,
        Field::SecondChunkType,
    ]);
    let value = prop_oneof![
        2 => select(vec![0u32, 1, 2, 3, 4, 7, 8, 12, 20, 1 << 16, 0x7FFF_FFFF, 0x8000_0000, u32::MAX - 3, u32::MAX, CHUNK_JSON, CHUNK_BIN]).prop_map(Word::Abs),
        2 => select(vec![-9i64, -8, -4, -1, 1, 3, 4, 8, 1 << 20]).prop_map(Word::Rel),
        1 => any::<u32>().prop_map(Word::Abs),
    ];
    prop_oneof![
        3 => (field, value).prop_map(|(field, value)| ByteMutation::Header { field, value }),
        4 => (0u8..4, any::<Index>(), 1u8..=255).prop_map(|(region, at, xor)| ByteMutation::Flip { region, at, xor }),
        1 => any::<Index>().prop_map(|at| ByteMutation::Truncate { at }),
    ]
    .boxed()
}

pub(crate) fn glb_case() -> impl Strategy<Value = GlbCase> {
    let layout = prop_oneof![
        12 => Just(Layout::Standard),
        1 => Just(Layout::NoBin),
        1 => Just(Layout::BinFirst),
        1 => Just(Layout::TwoJson),
        1 => any::<bool>().prop_map(|first| Layout::UnknownChunk { first }),
        1 => Just(Layout::EmptyBin),
        1 => Just(Layout::UnpaddedJson),
        1 => prop::collection::vec(any::<u8>(), 1..40).prop_map(Layout::Trailing),
    ];
    (
        prop_oneof![1 => Just(Vec::new()), 3 => prop::collection::vec(json_mutation(), 1..=MAX_MUTATIONS)],
        prop_oneof![3 => Just(Vec::new()), 1 => prop::collection::vec(bin_mutation(), 1..=2)],
        prop_oneof![7 => Just(None), 1 => text_mutation().prop_map(Some)],
        layout,
        prop_oneof![1 => Just(Vec::new()), 1 => prop::collection::vec(byte_mutation(), 1..=3)],
    )
        .prop_map(|(json, bin, text, layout, bytes)| GlbCase { json, bin, text, layout, bytes })
}

/// Packs chunks into a GLB: `(type, data, pad)` each, padded to 4 bytes with `pad`.
pub(crate) fn pack(chunks: &[(u32, &[u8], Option<u8>)]) -> Vec<u8> {
    let mut out = b"glTF".to_vec();
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    for &(kind, data, pad) in chunks {
        let padded = if pad.is_some() { data.len().next_multiple_of(4) } else { data.len() };
        out.extend_from_slice(&(padded as u32).to_le_bytes());
        out.extend_from_slice(&kind.to_le_bytes());
        out.extend_from_slice(data);
        out.resize(out.len() + padded - data.len(), pad.unwrap_or(0));
    }
    let len = out.len() as u32;
    out[8..12].copy_from_slice(&len.to_le_bytes());
    out
}

pub(crate) fn glb_bytes(f: &Fixture, case: &GlbCase) -> Vec<u8> {
    let (json, bin) = mutated(f, &case.json, &case.bin, case.text.as_ref());
    let (j, b) = (Some(b' '), Some(0u8));
    let mut glb = match &case.layout {
        Layout::Standard => pack(&[(CHUNK_JSON, &json, j), (CHUNK_BIN, &bin, b)]),
        Layout::NoBin => pack(&[(CHUNK_JSON, &json, j)]),
        Layout::BinFirst => pack(&[(CHUNK_BIN, &bin, b), (CHUNK_JSON, &json, j)]),
        Layout::TwoJson => pack(&[
            (CHUNK_JSON, br#"{"asset":{"version":"2.0"}}"#, j),
            (CHUNK_JSON, &json, j),
            (CHUNK_BIN, &bin, b),
        ]),
        Layout::UnknownChunk { first: true } => {
            pack(&[(0x1234_5678, b"junk", b), (CHUNK_JSON, &json, j), (CHUNK_BIN, &bin, b)])
        }
        Layout::UnknownChunk { first: false } => {
            pack(&[(CHUNK_JSON, &json, j), (0x1234_5678, b"junk!", b), (CHUNK_BIN, &bin, b)])
        }
        Layout::EmptyBin => pack(&[(CHUNK_JSON, &json, j), (CHUNK_BIN, &[], b)]),
        Layout::UnpaddedJson => pack(&[(CHUNK_JSON, &json, None), (CHUNK_BIN, &bin, b)]),
        Layout::Trailing(t) => {
            let mut g = pack(&[(CHUNK_JSON, &json, j), (CHUNK_BIN, &bin, b)]);
            g.extend_from_slice(t);
            g
        }
    };
    let first_len = u32::from_le_bytes(glb[12..16].try_into().expect("4 bytes")) as usize;
    let second = 20 + first_len;
    let json_region = 20..second.min(glb.len());
    let bin_region = (second + 8).min(glb.len())..glb.len();
    for m in &case.bytes {
        match m {
            ByteMutation::Header { field, value } => {
                let at = match field {
                    Field::Magic => 0,
                    Field::Version => 4,
                    Field::Length => 8,
                    Field::FirstChunkLength => 12,
                    Field::FirstChunkType => 16,
                    Field::SecondChunkLength => second,
                    Field::SecondChunkType => second + 4,
                };
                if at + 4 <= glb.len() {
                    let old = u32::from_le_bytes(glb[at..at + 4].try_into().expect("4 bytes"));
                    let new = match value {
                        Word::Abs(v) => *v,
                        Word::Rel(d) => (i64::from(old) + d) as u32,
                    };
                    glb[at..at + 4].copy_from_slice(&new.to_le_bytes());
                }
            }
            ByteMutation::Flip { region, at, xor } => {
                let r = match region {
                    0 => 0..20.min(glb.len()),
                    1 => json_region.start.min(glb.len())..json_region.end.min(glb.len()),
                    2 => bin_region.start.min(glb.len())..glb.len(),
                    _ => 0..glb.len(),
                };
                if !r.is_empty() {
                    let i = r.start + at.index(r.len());
                    glb[i] ^= xor;
                }
            }
            ByteMutation::Truncate { at } => glb.truncate(at.index(glb.len() + 1)),
        }
    }
    glb
}
