//! The three machine axes: names for messages and faults, and the serde form of per-axis
//! values.
//!
//! Per-axis configuration values are `[T; 3]` in memory (X, Y, Z). In human-readable files
//! (TOML scenarios, settings exports) they are written as a table `{ x = .., y = .., z = .. }`
//! or as an array of three; in binary formats (postcard: the host link and the settings
//! store) as a plain tuple. Use `#[serde(with = "crate::axes::per_axis")]` on such fields.

/// Number of axes.
pub const AXES: usize = 3;

/// One machine axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum Axis {
    X,
    Y,
    Z,
}

impl Axis {
    /// All axes in index order.
    pub const ALL: [Axis; AXES] = [Axis::X, Axis::Y, Axis::Z];

    /// Index into per-axis arrays.
    pub const fn index(self) -> usize {
        self as usize
    }

    /// Lower-case name (`x`, `y`, `z`).
    pub const fn name(self) -> &'static str {
        match self {
            Self::X => "x",
            Self::Y => "y",
            Self::Z => "z",
        }
    }

    /// The axis of index `i` (0..3).
    pub const fn from_index(i: usize) -> Option<Self> {
        match i {
            0 => Some(Self::X),
            1 => Some(Self::Y),
            2 => Some(Self::Z),
            _ => None,
        }
    }
}

/// serde for `[T; 3]` as `{x, y, z}` (or `[a, b, c]`) in human-readable formats and a
/// tuple in binary ones.
#[cfg(feature = "serde")]
pub mod per_axis {
    use core::fmt;
    use core::marker::PhantomData;
    use serde::de::{self, MapAccess, SeqAccess, Visitor};
    use serde::ser::{SerializeStruct, SerializeTuple};
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer, T: Serialize>(v: &[T; 3], s: S) -> Result<S::Ok, S::Error> {
        if s.is_human_readable() {
            let mut st = s.serialize_struct("PerAxis", 3)?;
            st.serialize_field("x", &v[0])?;
            st.serialize_field("y", &v[1])?;
            st.serialize_field("z", &v[2])?;
            st.end()
        } else {
            let mut t = s.serialize_tuple(3)?;
            for x in v {
                t.serialize_element(x)?;
            }
            t.end()
        }
    }

    struct PerAxisVisitor<T>(PhantomData<T>);

    impl<'de, T: Deserialize<'de>> Visitor<'de> for PerAxisVisitor<T> {
        type Value = [T; 3];

        fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
            f.write_str("a table with keys x, y and z, or an array of three values")
        }

        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<[T; 3], A::Error> {
            let x = seq
                .next_element()?
                .ok_or_else(|| de::Error::invalid_length(0, &self))?;
            let y = seq
                .next_element()?
                .ok_or_else(|| de::Error::invalid_length(1, &self))?;
            let z = seq
                .next_element()?
                .ok_or_else(|| de::Error::invalid_length(2, &self))?;
            if seq.next_element::<de::IgnoredAny>()?.is_some() {
                return Err(de::Error::invalid_length(4, &self));
            }
            Ok([x, y, z])
        }

        fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<[T; 3], A::Error> {
            let (mut x, mut y, mut z) = (None, None, None);
            while let Some(key) = map.next_key::<Key>()? {
                let slot = match key {
                    Key::X => &mut x,
                    Key::Y => &mut y,
                    Key::Z => &mut z,
                };
                if slot.is_some() {
                    return Err(de::Error::custom("axis given twice"));
                }
                *slot = Some(map.next_value()?);
            }
            Ok([
                x.ok_or_else(|| de::Error::missing_field("x"))?,
                y.ok_or_else(|| de::Error::missing_field("y"))?,
                z.ok_or_else(|| de::Error::missing_field("z"))?,
            ])
        }
    }

    #[derive(serde::Deserialize)]
    #[serde(rename_all = "snake_case")]
    enum Key {
        X,
        Y,
        Z,
    }

    pub fn deserialize<'de, D: Deserializer<'de>, T: Deserialize<'de>>(
        d: D,
    ) -> Result<[T; 3], D::Error> {
        if d.is_human_readable() {
            d.deserialize_any(PerAxisVisitor(PhantomData))
        } else {
            d.deserialize_tuple(3, PerAxisVisitor(PhantomData))
        }
    }
}
