//! JSON paths and what lives at them.

use super::*;

#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Seg {
    Key(String),
    At(usize),
}

pub(crate) type JsonPath = Vec<Seg>;

pub(crate) fn all_paths(v: &Value) -> Vec<JsonPath> {
    fn walk(v: &Value, prefix: &mut JsonPath, out: &mut Vec<JsonPath>) {
        out.push(prefix.clone());
        match v {
            Value::Object(m) => {
                for (k, c) in m {
                    prefix.push(Seg::Key(k.clone()));
                    walk(c, prefix, out);
                    prefix.pop();
                }
            }
            Value::Array(a) => {
                for (i, c) in a.iter().enumerate() {
                    prefix.push(Seg::At(i));
                    walk(c, prefix, out);
                    prefix.pop();
                }
            }
            _ => {}
        }
    }
    let mut out = Vec::new();
    walk(v, &mut Vec::new(), &mut out);
    out
}

pub(crate) fn get_mut<'a>(v: &'a mut Value, path: &[Seg]) -> Option<&'a mut Value> {
    path.iter().try_fold(v, |v, s| match s {
        Seg::Key(k) => v.get_mut(k.as_str()),
        Seg::At(i) => v.get_mut(*i),
    })
}

pub(crate) fn get<'a>(v: &'a Value, path: &[Seg]) -> Option<&'a Value> {
    path.iter().try_fold(v, |v, s| match s {
        Seg::Key(k) => v.get(k.as_str()),
        Seg::At(i) => v.get(*i),
    })
}

/// The glTF objects mutated field by field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    Root,
    Asset,
    Accessor,
    Sparse,
    SparseIndices,
    SparseValues,
    BufferView,
    Buffer,
    Mesh,
    Primitive,
    Attributes,
    Node,
    Material,
    Pbr,
    TextureInfo,
    Texture,
    Image,
    Sampler,
    Camera,
    Perspective,
    Scene,
}

/// What the object at `path` is, from the path's shape (indices written `#`).
pub(crate) fn kind_of(path: &[Seg]) -> Option<Kind> {
    let shape: Vec<&str> = path.iter().map(|s| if let Seg::Key(k) = s { k.as_str() } else { "#" }).collect();
    Some(match shape.join("/").as_str() {
        "" => Kind::Root,
        "asset" => Kind::Asset,
        "accessors/#" => Kind::Accessor,
        "accessors/#/sparse" => Kind::Sparse,
        "accessors/#/sparse/indices" => Kind::SparseIndices,
        "accessors/#/sparse/values" => Kind::SparseValues,
        "bufferViews/#" => Kind::BufferView,
        "buffers/#" => Kind::Buffer,
        "meshes/#" => Kind::Mesh,
        "meshes/#/primitives/#" => Kind::Primitive,
        "meshes/#/primitives/#/attributes" => Kind::Attributes,
        "nodes/#" => Kind::Node,
        "materials/#" => Kind::Material,
        "materials/#/pbrMetallicRoughness" => Kind::Pbr,
        "materials/#/pbrMetallicRoughness/baseColorTexture" | "materials/#/emissiveTexture" => {
            Kind::TextureInfo
        }
        "textures/#" => Kind::Texture,
        "images/#" => Kind::Image,
        "samplers/#" => Kind::Sampler,
        "cameras/#" => Kind::Camera,
        "cameras/#/perspective" => Kind::Perspective,
        "scenes/#" => Kind::Scene,
        _ => return None,
    })
}

/// Every field the loader reads, the objects that have it, and what it holds.
pub(crate) const FIELDS: &[(&str, &[Kind], Class)] = {
    use Class as C;
    use Kind as K;
    &[
        ("bufferView", &[K::Accessor, K::SparseIndices, K::SparseValues, K::Image], C::Index),
        ("byteOffset", &[K::Accessor, K::BufferView, K::SparseIndices, K::SparseValues], C::Size),
        ("componentType", &[K::Accessor, K::SparseIndices], C::Component),
        ("normalized", &[K::Accessor], C::Bool),
        ("count", &[K::Accessor, K::Sparse], C::Size),
        ("type", &[K::Accessor], C::AccessorType),
        ("sparse", &[K::Accessor], C::Sparse),
        ("indices", &[K::Sparse], C::SparseRef),
        ("values", &[K::Sparse], C::SparseRef),
        ("min", &[K::Accessor], C::Numbers(3)),
        ("buffer", &[K::BufferView], C::Index),
        ("byteLength", &[K::BufferView, K::Buffer], C::Size),
        ("byteStride", &[K::BufferView], C::Stride),
        ("uri", &[K::Buffer, K::Image], C::Uri),
        ("primitives", &[K::Mesh], C::Array),
        ("attributes", &[K::Primitive], C::Attributes),
        ("indices", &[K::Primitive], C::Index),
        ("material", &[K::Primitive], C::Index),
        ("mode", &[K::Primitive], C::Mode),
        (
            "extensions",
            &[
                K::Primitive,
                K::Node,
                K::Material,
                K::TextureInfo,
                K::Texture,
                K::Root,
                K::Accessor,
                K::BufferView,
                K::Mesh,
            ],
            C::Extensions,
        ),
        ("POSITION", &[K::Attributes], C::Index),
        ("NORMAL", &[K::Attributes], C::Index),
        ("TANGENT", &[K::Attributes], C::Index),
        ("TEXCOORD_0", &[K::Attributes], C::Index),
        ("TEXCOORD_1", &[K::Attributes], C::Index),
        ("children", &[K::Node], C::IndexList),
        ("mesh", &[K::Node], C::Index),
        ("camera", &[K::Node], C::Index),
        ("skin", &[K::Node], C::Index),
        ("matrix", &[K::Node], C::Numbers(16)),
        ("translation", &[K::Node], C::Numbers(3)),
        ("rotation", &[K::Node], C::Numbers(4)),
        ("scale", &[K::Node], C::Numbers(3)),
        ("name", &[K::Node, K::Mesh, K::Material, K::Camera], C::Str),
        ("alphaMode", &[K::Material], C::Str),
        ("alphaCutoff", &[K::Material], C::Number),
        ("doubleSided", &[K::Material], C::Bool),
        ("emissiveFactor", &[K::Material], C::Numbers(3)),
        ("emissiveTexture", &[K::Material], C::TextureInfo),
        ("pbrMetallicRoughness", &[K::Material], C::Object),
        ("baseColorFactor", &[K::Pbr], C::Numbers(4)),
        ("baseColorTexture", &[K::Pbr], C::TextureInfo),
        ("index", &[K::TextureInfo], C::Index),
        ("texCoord", &[K::TextureInfo], C::Index),
        ("source", &[K::Texture], C::Index),
        ("sampler", &[K::Texture], C::Index),
        ("mimeType", &[K::Image], C::Str),
        ("wrapS", &[K::Sampler], C::Component),
        ("type", &[K::Camera], C::Str),
        ("perspective", &[K::Camera], C::Object),
        ("yfov", &[K::Perspective], C::Number),
        ("aspectRatio", &[K::Perspective], C::Number),
        ("nodes", &[K::Scene, K::Root], C::IndexList),
        ("scene", &[K::Root], C::Index),
        ("scenes", &[K::Root], C::Array),
        ("meshes", &[K::Root], C::Array),
        ("accessors", &[K::Root], C::Array),
        ("bufferViews", &[K::Root], C::Array),
        ("buffers", &[K::Root], C::Array),
        ("samplers", &[K::Root], C::Array),
        ("extensionsRequired", &[K::Root], C::ExtensionNames),
        ("extensionsUsed", &[K::Root], C::ExtensionNames),
        ("asset", &[K::Root], C::Object),
        ("version", &[K::Asset], C::Str),
    ]
};
