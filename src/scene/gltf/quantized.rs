//! Vertex attributes in every component type core glTF and KHR_mesh_quantization allow, read as floats.
use super::Loader;
use gltf::accessor::{DataType, Item, Iter};

use DataType::{F32, I16, I8, U16, U8};

/// (component type, normalized) pairs each attribute may use. Integers that are not normalized are read as their
/// values (gltfpack puts the dequantising scale in the node's transform).
pub(super) const POSITION_TYPES: &[(DataType, bool)] = &[
    (F32, false),
    (I8, false),
    (I8, true),
    (U8, false),
    (U8, true),
    (I16, false),
    (I16, true),
    (U16, false),
    (U16, true),
];
/// NORMAL and TANGENT: unit vectors, so integers must be normalized (and signed).
pub(super) const UNIT_TYPES: &[(DataType, bool)] = &[(F32, false), (I8, true), (I16, true)];
pub(super) const TEXCOORD_TYPES: &[(DataType, bool)] = POSITION_TYPES;
/// Morph-target displacements: signed, normalized or not.
pub(super) const MORPH_TYPES: &[(DataType, bool)] = &[(F32, false), (I8, false), (I8, true), (I16, false), (I16, true)];

/// A component as a float: normalized integers by glTF's rules (signed ones clamped at -1).
trait Component: Item + Copy {
    fn to_f32(self, normalized: bool) -> f32;
}

impl Component for f32 {
    fn to_f32(self, _: bool) -> f32 {
        self
    }
}

macro_rules! integer_component {
    ($t:ty, $max:expr, $signed:expr) => {
        impl Component for $t {
            fn to_f32(self, normalized: bool) -> f32 {
                match (normalized, $signed) {
                    (false, _) => self as f32,
                    (true, true) => (self as f32 / $max).max(-1.0),
                    (true, false) => self as f32 / $max,
                }
            }
        }
    };
}
integer_component!(i8, 127.0, true);
integer_component!(u8, 255.0, false);
integer_component!(i16, 32767.0, true);
integer_component!(u16, 65535.0, false);

impl Loader<'_> {
    /// The accessor's elements as N floats each; `None` when it holds no data (gltf's reader yields nothing then).
    /// The accessor must have passed `check_accessor_types` for N components of an allowed type.
    pub(super) fn read_floats<const N: usize>(&self, acc: &gltf::Accessor) -> Option<Vec<[f32; N]>>
    where
        [i8; N]: Item,
        [u8; N]: Item,
        [i16; N]: Item,
        [u16; N]: Item,
        [f32; N]: Item,
    {
        let normalized = acc.normalized();
        match acc.data_type() {
            F32 => self.read_as::<f32, N>(acc, normalized),
            I8 => self.read_as::<i8, N>(acc, normalized),
            U8 => self.read_as::<u8, N>(acc, normalized),
            I16 => self.read_as::<i16, N>(acc, normalized),
            U16 => self.read_as::<u16, N>(acc, normalized),
            DataType::U32 => None,
        }
    }

    /// `read_floats` for SCALAR accessors (gltf reads them as plain components, not one-element arrays).
    pub(super) fn read_scalars(&self, acc: &gltf::Accessor) -> Option<Vec<f32>> {
        let normalized = acc.normalized();
        match acc.data_type() {
            F32 => self.read_scalars_as::<f32>(acc, normalized),
            I8 => self.read_scalars_as::<i8>(acc, normalized),
            U8 => self.read_scalars_as::<u8>(acc, normalized),
            I16 => self.read_scalars_as::<i16>(acc, normalized),
            U16 => self.read_scalars_as::<u16>(acc, normalized),
            DataType::U32 => None,
        }
    }

    fn read_scalars_as<T: Component>(&self, acc: &gltf::Accessor, normalized: bool) -> Option<Vec<f32>> {
        let buffers = self.buffers;
        let iter: Iter<'_, T> = Iter::new(acc.clone(), |b: gltf::Buffer| buffers.get(b.index()).map(|d| &d[..]))?;
        Some(iter.map(|c| c.to_f32(normalized)).collect())
    }

    fn read_as<T: Component, const N: usize>(&self, acc: &gltf::Accessor, normalized: bool) -> Option<Vec<[f32; N]>>
    where
        [T; N]: Item,
    {
        let buffers = self.buffers;
        let iter: Iter<'_, [T; N]> = Iter::new(acc.clone(), |b: gltf::Buffer| buffers.get(b.index()).map(|d| &d[..]))?;
        Some(iter.map(|v| v.map(|c| c.to_f32(normalized))).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::Component;

    #[test]
    fn normalized_integers_follow_gltf_rules() {
        assert_eq!(127i8.to_f32(true), 1.0);
        assert_eq!((-127i8).to_f32(true), -1.0);
        // -128 is below -1 after dividing by 127: glTF clamps it.
        assert_eq!((-128i8).to_f32(true), -1.0);
        assert_eq!((-32768i16).to_f32(true), -1.0);
        assert_eq!(255u8.to_f32(true), 1.0);
        assert_eq!(65535u16.to_f32(true), 1.0);
        assert_eq!(32767u16.to_f32(true), 32767.0 / 65535.0);
        // Not normalized: the integer's value (gltfpack scales it back in the node's transform).
        assert_eq!(65535u16.to_f32(false), 65535.0);
        assert_eq!((-5i8).to_f32(false), -5.0);
    }
}
