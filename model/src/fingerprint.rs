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
    let mut bytes = Vec::new();
    ciborium::into_writer(value, &mut bytes).ok()?;
    let mut hash = xxhash_rust::xxh3::Xxh3::new();
    hash.update(&bytes);
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
