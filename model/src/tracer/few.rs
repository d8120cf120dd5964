//! [`Few`]: a list of `Copy` values kept inline up to `N` and on the heap beyond, for the short
//! lists of a ray's outcomes (a candidate's reports, the committable candidates) that would
//! otherwise cost an allocation each. It reads as a slice, and prints, compares and serialises as
//! the `Vec` it stands for.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Up to `N` values inline, more in a `Vec`.
#[derive(Clone)]
pub struct Few<T: Copy, const N: usize>(Repr<T, N>);

#[derive(Clone)]
enum Repr<T: Copy, const N: usize> {
    Empty,
    /// The first `len` slots are the values; the others copies of the first.
    Inline(u8, [T; N]),
    Heap(Vec<T>),
}

impl<T: Copy, const N: usize> Few<T, N> {
    /// The empty list.
    pub const fn new() -> Few<T, N> {
        Few(Repr::Empty)
    }

    /// Appends a value.
    pub fn push(&mut self, x: T) {
        match &mut self.0 {
            Repr::Empty => self.0 = Repr::Inline(1, [x; N]),
            Repr::Inline(len, items) if (*len as usize) < N => {
                items[*len as usize] = x;
                *len += 1;
            }
            Repr::Inline(len, items) => {
                let mut v = Vec::with_capacity(2 * N);
                v.extend_from_slice(&items[..*len as usize]);
                v.push(x);
                self.0 = Repr::Heap(v);
            }
            Repr::Heap(v) => v.push(x),
        }
    }
}

impl<T: Copy, const N: usize> Default for Few<T, N> {
    fn default() -> Self {
        Few::new()
    }
}

impl<T: Copy, const N: usize> std::ops::Deref for Few<T, N> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        match &self.0 {
            Repr::Empty => &[],
            Repr::Inline(len, items) => &items[..*len as usize],
            Repr::Heap(v) => v,
        }
    }
}

impl<T: Copy, const N: usize> FromIterator<T> for Few<T, N> {
    fn from_iter<I: IntoIterator<Item = T>>(iter: I) -> Self {
        let mut out = Few::new();
        for x in iter {
            out.push(x);
        }
        out
    }
}

impl<'a, T: Copy, const N: usize> IntoIterator for &'a Few<T, N> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

impl<T: Copy + std::fmt::Debug, const N: usize> std::fmt::Debug for Few<T, N> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        (**self).fmt(f)
    }
}

impl<T: Copy + PartialEq, const N: usize> PartialEq for Few<T, N> {
    fn eq(&self, o: &Self) -> bool {
        **self == **o
    }
}

impl<T: Copy + Serialize, const N: usize> Serialize for Few<T, N> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.iter())
    }
}

impl<'de, T: Copy + Deserialize<'de>, const N: usize> Deserialize<'de> for Few<T, N> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Ok(Vec::<T>::deserialize(d)?.into_iter().collect())
    }
}

#[cfg(test)]
mod tests {
    use super::Few;

    #[test]
    fn a_few_reads_prints_and_serialises_as_its_vec() {
        for n in 0..6usize {
            let v: Vec<usize> = (0..n).map(|i| 10 * i + 1).collect();
            let f: Few<usize, 2> = v.iter().copied().collect();
            assert_eq!(&*f, &v[..]);
            assert_eq!(format!("{f:?}"), format!("{v:?}"));
            assert_eq!(format!("{f:#?}"), format!("{v:#?}"));
            let json = serde_json::to_string(&f).unwrap();
            assert_eq!(json, serde_json::to_string(&v).unwrap());
            let back: Few<usize, 2> = serde_json::from_str(&json).unwrap();
            assert!(back == f);
        }
    }
}
