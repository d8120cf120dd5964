//! Where a value sits in a YAML file: a dotted path (`world.launch.scene.instances[2].transform`)
//! resolved to the line and column of its node, by walking the document with serde_yaml's own parser
//! and stopping with an error at the node (serde_yaml attaches the node's position to it).

use serde::de::{DeserializeSeed, Deserializer, EnumAccess, Error, MapAccess, SeqAccess, Visitor};

/// The segments of a path: `a.b[2].c` → `a`, `b`, `[2]`, `c`.
fn segments(path: &str) -> Vec<String> {
    let mut out = Vec::new();
    for part in path.split('.') {
        let mut rest = part;
        while let Some(open) = rest.find('[') {
            if open > 0 {
                out.push(rest[..open].to_string());
            }
            let close = rest[open..].find(']').map_or(rest.len(), |c| open + c + 1);
            out.push(rest[open..close].to_string());
            rest = &rest[close..];
        }
        if !rest.is_empty() {
            out.push(rest.to_string());
        }
    }
    out
}

/// The 1-based line and column of the node at `path` in `text`, None when the path names no node (or
/// the text is not YAML).
pub fn locate(text: &str, path: &str) -> Option<(usize, usize)> {
    let target = segments(path);
    let de = serde_yaml::Deserializer::from_str(text);
    match (Find {
        target: &target,
        depth: 0,
    })
    .deserialize(de)
    {
        Err(e) if e.to_string().contains(MARK) => e.location().map(|l| (l.line(), l.column())),
        _ => None,
    }
}

const MARK: &str = "rtconf-locate: found";

struct Find<'a> {
    target: &'a [String],
    depth: usize,
}

impl<'de> DeserializeSeed<'de> for Find<'_> {
    type Value = ();
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        if self.depth == self.target.len() {
            return d.deserialize_any(Stop);
        }
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for Find<'_> {
    type Value = ();
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "any YAML node")
    }
    fn visit_map<A: MapAccess<'de>>(self, mut m: A) -> Result<(), A::Error> {
        while let Some(k) = m.next_key::<serde_yaml::Value>()? {
            let key = match &k {
                serde_yaml::Value::String(s) => s.clone(),
                other => serde_yaml::to_string(other)
                    .unwrap_or_default()
                    .trim()
                    .to_string(),
            };
            if key == self.target[self.depth] {
                m.next_value_seed(Find {
                    target: self.target,
                    depth: self.depth + 1,
                })?;
            } else {
                m.next_value::<serde::de::IgnoredAny>()?;
            }
        }
        Ok(())
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut s: A) -> Result<(), A::Error> {
        let mut i = 0usize;
        loop {
            let more = if format!("[{i}]") == self.target[self.depth] {
                s.next_element_seed(Find {
                    target: self.target,
                    depth: self.depth + 1,
                })?
                .is_some()
            } else {
                s.next_element::<serde::de::IgnoredAny>()?.is_some()
            };
            if !more {
                return Ok(());
            }
            i += 1;
        }
    }
    fn visit_enum<A: EnumAccess<'de>>(self, e: A) -> Result<(), A::Error> {
        use serde::de::VariantAccess;
        let (_, v): (serde_yaml::Value, _) = e.variant()?;
        v.newtype_variant_seed(self)
    }
    fn visit_str<E: Error>(self, _: &str) -> Result<(), E> {
        Ok(())
    }
    fn visit_f64<E: Error>(self, _: f64) -> Result<(), E> {
        Ok(())
    }
    fn visit_u64<E: Error>(self, _: u64) -> Result<(), E> {
        Ok(())
    }
    fn visit_i64<E: Error>(self, _: i64) -> Result<(), E> {
        Ok(())
    }
    fn visit_bool<E: Error>(self, _: bool) -> Result<(), E> {
        Ok(())
    }
    fn visit_unit<E: Error>(self) -> Result<(), E> {
        Ok(())
    }
}

/// Rejects whatever node it is given, so the error carries that node's position.
struct Stop;

impl<'de> Visitor<'de> for Stop {
    type Value = ();
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "nothing")
    }
    fn visit_map<A: MapAccess<'de>>(self, _: A) -> Result<(), A::Error> {
        Err(A::Error::custom(MARK))
    }
    fn visit_seq<A: SeqAccess<'de>>(self, _: A) -> Result<(), A::Error> {
        Err(A::Error::custom(MARK))
    }
    fn visit_enum<A: EnumAccess<'de>>(self, _: A) -> Result<(), A::Error> {
        Err(A::Error::custom(MARK))
    }
    fn visit_str<E: Error>(self, _: &str) -> Result<(), E> {
        Err(E::custom(MARK))
    }
    fn visit_f64<E: Error>(self, _: f64) -> Result<(), E> {
        Err(E::custom(MARK))
    }
    fn visit_u64<E: Error>(self, _: u64) -> Result<(), E> {
        Err(E::custom(MARK))
    }
    fn visit_i64<E: Error>(self, _: i64) -> Result<(), E> {
        Err(E::custom(MARK))
    }
    fn visit_bool<E: Error>(self, _: bool) -> Result<(), E> {
        Err(E::custom(MARK))
    }
    fn visit_unit<E: Error>(self) -> Result<(), E> {
        Err(E::custom(MARK))
    }
}

#[cfg(test)]
mod tests {
    use super::locate;

    #[test]
    fn paths_resolve_to_their_nodes() {
        let text = "a:\n  b: [1, 2, {c: 3}]\n  d: !tag\n    e: 5\n    f:\n      - 1\n      - 7\n";
        assert_eq!(locate(text, "a.b[2].c"), Some((2, 17)));
        assert_eq!(locate(text, "a.d.f[1]"), Some((7, 9)));
        assert_eq!(locate(text, "a.d"), Some((3, 6)));
        assert_eq!(locate(text, "a.x"), None);
        assert_eq!(locate(": :", "a"), None);
    }
}
