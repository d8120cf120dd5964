//! Content fingerprints: 128 bits of a value's serde form in CBOR (every float bit for bit), for
//! memoising what the model derives from large values (a launch's scene and rays) across the gate,
//! the rules and the judgement of one case without holding or comparing the values themselves.

/// The fingerprint of `value`: equal values always get equal fingerprints; different ones differ
/// but with a chance of about 2^-128. None when the value does not serialise.
pub fn of<T: serde::Serialize + ?Sized>(value: &T) -> Option<u128> {
    of_with_words(value, &[])
}

/// Bytes of the words of [`of_with_words`] handed to the hash at a time.
const WORD_CHUNK: usize = 1024;

/// The fingerprint of `value` followed by `words` (taken as they are: a long run of plain words,
/// such as a launch's ray keys, costs a copy instead of a CBOR item each).
///
/// The hash is XXH3's 128-bit one: the values are the model's own (scenes, rays, calls), never
/// chosen to collide, for which its 128 bits give the 2^-128 chance above. It runs at a fraction
/// of an instruction per byte; a launch's scene and ray keys are hundreds of kilobytes, and the
/// gate, the rules and the judgement of one case each fingerprint them again to find what the
/// first one derived.
pub fn of_with_words<T: serde::Serialize + ?Sized>(value: &T, words: &[u32]) -> Option<u128> {
    let mut sink = HashSink {
        hash: xxhash_rust::xxh3::Xxh3::new(),
        held: [0; HELD],
        len: 0,
    };
    ciborium::into_writer(value, &mut sink).ok()?;
    let HashSink {
        mut hash,
        held,
        len,
        ..
    } = sink;
    hash.update(&held[..len]);
    hash.update(&(words.len() as u64).to_le_bytes());
    let mut chunk = [0u8; WORD_CHUNK];
    for part in words.chunks(WORD_CHUNK / 4) {
        for (out, w) in chunk.chunks_exact_mut(4).zip(part) {
            out.copy_from_slice(&w.to_le_bytes());
        }
        hash.update(&chunk[..part.len() * 4]);
    }
    Some(hash.digest128())
}

/// Bytes of CBOR a [`HashSink`] holds before handing them to the hash.
const HELD: usize = 4096;

/// The CBOR of a value handed to the hash as it is written, never held whole: the encoder's many
/// short writes (an item's header, a small number) gathered into `held`, a long one (a bulk byte
/// string) hashed where it lies. The hash of the bytes is the same however they are split.
struct HashSink {
    hash: xxhash_rust::xxh3::Xxh3,
    held: [u8; HELD],
    len: usize,
}

impl std::io::Write for HashSink {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        if self.len + bytes.len() > HELD {
            self.hash.update(&self.held[..self.len]);
            self.len = 0;
        }
        if bytes.len() >= HELD {
            self.hash.update(bytes);
        } else {
            self.held[self.len..self.len + bytes.len()].copy_from_slice(bytes);
            self.len += bytes.len();
        }
        Ok(bytes.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Values kept by fingerprint, at most `KEPT` of them (all forgotten when full): a memo for `static`s.
pub struct Memo<V, const KEPT: usize> {
    map: std::sync::Mutex<Option<std::collections::HashMap<u128, V>>>,
}

impl<V: Clone, const KEPT: usize> Memo<V, KEPT> {
    pub const fn new() -> Self {
        Memo {
            map: std::sync::Mutex::new(None),
        }
    }

    /// The value kept for `key`, or `make`'s, kept for next time (no key: made, not kept).
    pub fn get_or(&self, key: Option<u128>, make: impl FnOnce() -> V) -> V {
        let Some(k) = key else { return make() };
        let lock = || self.map.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(v) = lock().as_ref().and_then(|m| m.get(&k)) {
            return v.clone();
        }
        let v = make();
        let mut map = lock();
        let m = map.get_or_insert_with(std::collections::HashMap::new);
        if m.len() >= KEPT {
            m.clear();
        }
        m.insert(k, v.clone());
        v
    }
}

impl<V: Clone, const KEPT: usize> Default for Memo<V, KEPT> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn equal_values_match_and_one_bit_tells_them_apart() {
        let a = vec![1.0f32, f32::NAN, -0.0];
        let b = vec![1.0f32, f32::NAN, 0.0];
        assert_eq!(super::of(&a), super::of(&a.clone()));
        assert_ne!(super::of(&a), super::of(&b));
        let nan_payload = vec![1.0f32, f32::from_bits(0x7fc0_0001), -0.0];
        assert_ne!(super::of(&a), super::of(&nan_payload));
        assert_ne!(
            super::of_with_words(&a, &[1, 2]),
            super::of_with_words(&a, &[1, 3])
        );
        assert_ne!(
            super::of_with_words(&a, &[]),
            super::of_with_words(&a, &[0])
        );
    }

    /// The fingerprint as the hash of the whole CBOR held at once, then the words.
    fn of_whole<T: serde::Serialize>(value: &T, words: &[u32]) -> u128 {
        let mut bytes = Vec::new();
        ciborium::into_writer(value, &mut bytes).expect("serialises");
        let mut hash = xxhash_rust::xxh3::Xxh3::new();
        hash.update(&bytes);
        hash.update(&(words.len() as u64).to_le_bytes());
        for w in words {
            hash.update(&w.to_le_bytes());
        }
        hash.digest128()
    }

    #[test]
    fn the_streamed_fingerprint_is_the_hash_of_the_whole_cbor() {
        #[derive(serde::Serialize)]
        struct Mixed {
            names: Vec<String>,
            #[serde(with = "crate::bulk")]
            positions: Vec<[f32; 3]>,
            small: Vec<u8>,
        }
        // Short items around byte strings shorter than, as long as, and longer than what the sink
        // holds, so every path of its write is taken.
        for n in [
            0,
            1,
            super::HELD / 12,
            super::HELD / 12 + 1,
            3 * super::HELD,
        ] {
            let value = Mixed {
                names: (0..40).map(|i| "x".repeat(i * 7)).collect(),
                positions: (0..n).map(|i| [i as f32, -0.5, f32::NAN]).collect(),
                small: (0..=255).collect(),
            };
            let words: Vec<u32> = (0..n as u32).collect();
            assert_eq!(
                super::of_with_words(&value, &words),
                Some(of_whole(&value, &words)),
                "{n} positions"
            );
        }
    }

    #[test]
    fn a_memo_makes_each_value_once_and_forgets_when_full() {
        let memo: super::Memo<u32, 2> = super::Memo::new();
        let mut made = 0;
        for k in [1u128, 1, 2, 1] {
            memo.get_or(Some(k), || {
                made += 1;
                k as u32
            });
        }
        assert_eq!(made, 2);
        assert_eq!(memo.get_or(Some(3), || 30), 30);
        assert_eq!(
            memo.get_or(Some(1), || 10),
            10,
            "a full memo forgets what it kept"
        );
        assert_eq!(memo.get_or(None, || 7), 7);
    }
}
