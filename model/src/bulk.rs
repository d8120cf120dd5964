//! Long runs of plain numbers — a scene's vertex positions, indices, boxes and spheres, a launch's
//! record words — in their serde form: a sequence of numbers in human-readable formats (the YAML of
//! case files, the JSON of reports, unchanged) and one byte string of little-endian numbers in binary
//! ones (the CBOR the runner and its workers hand each other, and that fingerprints hash), read back
//! bit for bit. A byte string costs a copy where a CBOR item per number costs a header each way.
//!
//! Use as `#[serde(with = "crate::bulk")]` on a `Vec<T>` of a [`Plain`] type.

use crate::scene::{Aabb, Ray, RayFlags, Sphere};
use serde::de::{Error, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::marker::PhantomData;

/// A value laid out as a fixed number of little-endian bytes.
pub trait Plain: Sized {
    /// Its size in bytes.
    const BYTES: usize;
    /// Writes its bytes into `out`, exactly [`Plain::BYTES`] of them.
    fn put(&self, out: &mut [u8]);
    /// Reads it back from exactly [`Plain::BYTES`] bytes.
    fn take(bytes: &[u8]) -> Self;
}

fn f32_at(bytes: &[u8], k: usize) -> f32 {
    f32::from_le_bytes([
        bytes[4 * k],
        bytes[4 * k + 1],
        bytes[4 * k + 2],
        bytes[4 * k + 3],
    ])
}

/// Writes `values` into the first `4 * values.len()` bytes of `out`.
fn put_f32s(values: &[f32], out: &mut [u8]) {
    for (o, v) in out.chunks_exact_mut(4).zip(values) {
        o.copy_from_slice(&v.to_le_bytes());
    }
}

impl Plain for u32 {
    const BYTES: usize = 4;
    fn put(&self, out: &mut [u8]) {
        out.copy_from_slice(&self.to_le_bytes());
    }
    fn take(b: &[u8]) -> Self {
        u32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }
}

impl Plain for u16 {
    const BYTES: usize = 2;
    fn put(&self, out: &mut [u8]) {
        out.copy_from_slice(&self.to_le_bytes());
    }
    fn take(b: &[u8]) -> Self {
        u16::from_le_bytes([b[0], b[1]])
    }
}

impl Plain for [f32; 3] {
    const BYTES: usize = 12;
    fn put(&self, out: &mut [u8]) {
        put_f32s(self, out);
    }
    fn take(b: &[u8]) -> Self {
        [0, 1, 2].map(|k| f32_at(b, k))
    }
}

impl Plain for Aabb {
    const BYTES: usize = 24;
    fn put(&self, out: &mut [u8]) {
        put_f32s(&self.min, &mut out[..12]);
        put_f32s(&self.max, &mut out[12..]);
    }
    fn take(b: &[u8]) -> Self {
        Aabb {
            min: [0, 1, 2].map(|k| f32_at(b, k)),
            max: [3, 4, 5].map(|k| f32_at(b, k)),
        }
    }
}

impl Plain for Sphere {
    const BYTES: usize = 16;
    fn put(&self, out: &mut [u8]) {
        put_f32s(&self.center, &mut out[..12]);
        put_f32s(&[self.radius], &mut out[12..]);
    }
    fn take(b: &[u8]) -> Self {
        Sphere {
            center: [0, 1, 2].map(|k| f32_at(b, k)),
            radius: f32_at(b, 3),
        }
    }
}

impl Plain for Ray {
    const BYTES: usize = 52;
    fn put(&self, out: &mut [u8]) {
        put_f32s(&self.origin, &mut out[..12]);
        put_f32s(&self.direction, &mut out[12..24]);
        put_f32s(&[self.tmin, self.tmax], &mut out[24..32]);
        let words = [
            self.flags.0,
            self.cull_mask,
            self.sbt_offset,
            self.sbt_stride,
            self.miss_index,
        ];
        for (o, w) in out[32..].chunks_exact_mut(4).zip(words) {
            w.put(o);
        }
    }
    fn take(b: &[u8]) -> Self {
        let word = |k: usize| u32::take(&b[4 * k..4 * k + 4]);
        Ray {
            origin: [0, 1, 2].map(|k| f32_at(b, k)),
            direction: [3, 4, 5].map(|k| f32_at(b, k)),
            tmin: f32_at(b, 6),
            tmax: f32_at(b, 7),
            flags: RayFlags(word(8)),
            cull_mask: word(9),
            sbt_offset: word(10),
            sbt_stride: word(11),
            miss_index: word(12),
        }
    }
}

/// The values as a sequence (human-readable formats) or as one byte string (binary formats).
pub fn serialize<T: Plain + Serialize, S: Serializer>(
    values: &[T],
    s: S,
) -> Result<S::Ok, S::Error> {
    if s.is_human_readable() {
        return values.serialize(s);
    }
    // Written in place, one fixed-size slot per value.
    let mut bytes = vec![0u8; values.len() * T::BYTES];
    for (slot, v) in bytes.chunks_exact_mut(T::BYTES).zip(values) {
        v.put(slot);
    }
    s.serialize_bytes(&bytes)
}

/// Reads what [`serialize`] wrote. A binary format's byte string must hold whole values; a sequence is
/// read in either kind of format.
pub fn deserialize<'de, T, D>(d: D) -> Result<Vec<T>, D::Error>
where
    T: Plain + Deserialize<'de>,
    D: Deserializer<'de>,
{
    if d.is_human_readable() {
        return Vec::<T>::deserialize(d);
    }
    d.deserialize_byte_buf(Values(PhantomData))
}

struct Values<T>(PhantomData<T>);

impl<'de, T: Plain + Deserialize<'de>> Visitor<'de> for Values<T> {
    type Value = Vec<T>;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(
            f,
            "a byte string of {}-byte values, or a sequence",
            T::BYTES
        )
    }

    fn visit_bytes<E: Error>(self, bytes: &[u8]) -> Result<Vec<T>, E> {
        if bytes.len() % T::BYTES != 0 {
            return Err(E::custom(format!(
                "a byte string of {} bytes is not a whole number of {}-byte values",
                bytes.len(),
                T::BYTES
            )));
        }
        Ok(bytes.chunks_exact(T::BYTES).map(T::take).collect())
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<T>, A::Error> {
        // The size hint is the input's claim: bounded, so a short input cannot reserve much.
        let mut out = Vec::with_capacity(seq.size_hint().unwrap_or(0).min(4096));
        while let Some(v) = seq.next_element()? {
            out.push(v);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct Holder {
        #[serde(with = "crate::bulk")]
        positions: Vec<[f32; 3]>,
        #[serde(with = "crate::bulk")]
        words: Vec<u32>,
        #[serde(with = "crate::bulk")]
        short: Vec<u16>,
        #[serde(with = "crate::bulk")]
        boxes: Vec<Aabb>,
        #[serde(with = "crate::bulk")]
        spheres: Vec<Sphere>,
        #[serde(with = "crate::bulk")]
        rays: Vec<Ray>,
    }

    fn holder() -> Holder {
        Holder {
            positions: vec![[1.5, -0.0, f32::NAN], [f32::INFINITY, 3e-41, -7.25]],
            words: vec![0, 1, u32::MAX, 0xDEAD_BEEF],
            short: vec![0, 65535, 7],
            boxes: vec![Aabb {
                min: [f32::NAN, -1.0, 2.0],
                max: [1.0, 2.0, 3.5],
            }],
            spheres: vec![Sphere {
                center: [0.25, 0.5, -0.75],
                radius: 1e-30,
            }],
            rays: vec![Ray {
                origin: [1.0, f32::NAN, -2.0],
                direction: [0.0, -0.0, 1.0],
                tmin: 0.5,
                tmax: f32::INFINITY,
                flags: RayFlags(0x301),
                cull_mask: 0x7F,
                sbt_offset: 3,
                sbt_stride: 15,
                miss_index: 65535,
            }],
        }
    }

    fn bits(h: &Holder) -> Vec<u32> {
        let mut out: Vec<u32> = h.positions.iter().flatten().map(|x| x.to_bits()).collect();
        out.extend(&h.words);
        out.extend(h.short.iter().map(|&s| s as u32));
        for b in &h.boxes {
            out.extend(b.min.iter().chain(&b.max).map(|x| x.to_bits()));
        }
        for s in &h.spheres {
            out.extend(s.center.iter().chain([&s.radius]).map(|x| x.to_bits()));
        }
        for r in &h.rays {
            let floats = r
                .origin
                .iter()
                .chain(&r.direction)
                .chain([&r.tmin, &r.tmax]);
            out.extend(floats.map(|x| x.to_bits()));
            out.extend([
                r.flags.0,
                r.cull_mask,
                r.sbt_offset,
                r.sbt_stride,
                r.miss_index,
            ]);
        }
        out
    }

    #[test]
    fn cbor_holds_byte_strings_read_back_bit_for_bit() {
        let h = holder();
        let mut bytes = Vec::new();
        ciborium::into_writer(&h, &mut bytes).unwrap();
        // Six byte strings: major type 2 headers, and no f32 item (0xfa) anywhere.
        let value: ciborium::Value = ciborium::from_reader(bytes.as_slice()).unwrap();
        let map = value.as_map().expect("a map");
        assert!(map.iter().all(|(_, v)| v.is_bytes()), "{value:?}");
        let back: Holder = ciborium::from_reader(bytes.as_slice()).unwrap();
        assert_eq!(bits(&back), bits(&h));
    }

    #[test]
    fn yaml_keeps_sequences_of_numbers() {
        let h = holder();
        let text = serde_yaml::to_string(&h).unwrap();
        assert!(
            text.contains("- 0xDEADBEEF") || text.contains("- 3735928559"),
            "{text}"
        );
        assert!(text.contains("- -7.25"), "{text}");
        let back: Holder = serde_yaml::from_str(&text).unwrap();
        assert_eq!(bits(&back), bits(&h));
    }

    #[test]
    fn a_torn_byte_string_is_an_error_not_a_panic() {
        let mut bytes = Vec::new();
        // A map with `words` as 5 bytes: not a whole number of 4-byte words.
        let value = ciborium::Value::Map(vec![(
            ciborium::Value::Text("words".into()),
            ciborium::Value::Bytes(vec![1, 2, 3, 4, 5]),
        )]);
        ciborium::into_writer(&value, &mut bytes).unwrap();
        #[derive(Debug, Deserialize)]
        struct Words {
            #[allow(dead_code)]
            #[serde(with = "crate::bulk")]
            words: Vec<u32>,
        }
        let e = ciborium::from_reader::<Words, _>(bytes.as_slice()).unwrap_err();
        assert!(
            e.to_string()
                .contains("not a whole number of 4-byte values"),
            "{e}"
        );
    }

    #[test]
    fn a_binary_sequence_still_reads() {
        // What an older runner or worker wrote: the numbers as CBOR items.
        #[derive(Serialize)]
        struct Plainly {
            words: Vec<u32>,
        }
        #[derive(Debug, Deserialize)]
        struct Words {
            #[serde(with = "crate::bulk")]
            words: Vec<u32>,
        }
        let mut bytes = Vec::new();
        ciborium::into_writer(
            &Plainly {
                words: vec![3, 1, 4],
            },
            &mut bytes,
        )
        .unwrap();
        let back: Words = ciborium::from_reader(bytes.as_slice()).unwrap();
        assert_eq!(back.words, vec![3, 1, 4]);
    }
}
