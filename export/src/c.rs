//! Writing C text: an indenting line writer, string and comment escaping, data arrays (bytes and
//! 32-bit words, in hex), addresses, and flag values with their Vulkan names in a comment.

use model::call::Address;

/// Lines of C with the current indentation.
#[derive(Default)]
pub(crate) struct Emitter {
    out: String,
    pub(crate) indent: usize,
}

impl Emitter {
    pub(crate) fn line(&mut self, l: &str) {
        if l.is_empty() {
            self.out.push('\n');
            return;
        }
        for _ in 0..self.indent {
            self.out.push_str("    ");
        }
        self.out.push_str(l);
        self.out.push('\n');
    }

    /// Text written as it is.
    pub(crate) fn raw(&mut self, text: &str) {
        self.out.push_str(text);
    }

    pub(crate) fn open(&mut self, l: &str) {
        self.line(l);
        self.indent += 1;
    }

    pub(crate) fn close(&mut self, l: &str) {
        self.indent = self.indent.saturating_sub(1);
        self.line(l);
    }

    pub(crate) fn finish(self) -> String {
        self.out
    }
}

/// A C string literal.
pub(crate) fn string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            c if c.is_ascii() && !c.is_ascii_control() => out.push(c),
            c => {
                let mut buf = [0u8; 4];
                for b in c.encode_utf8(&mut buf).bytes() {
                    out.push_str(&format!("\\{b:03o}"));
                }
            }
        }
    }
    out.push('"');
    out
}

/// Text that may stand inside a `/* */` comment.
pub(crate) fn comment_safe(s: &str) -> String {
    s.replace("*/", "* /")
}

/// `static const uint8_t NAME[] = {…};` (at least one byte, so the array is never empty).
pub(crate) fn bytes(e: &mut Emitter, name: &str, data: &[u8]) {
    e.line(&format!(
        "static const uint8_t {name}[{}] = {{",
        data.len().max(1)
    ));
    if data.is_empty() {
        e.line("    0");
    }
    for chunk in data.chunks(16) {
        let row: Vec<String> = chunk.iter().map(|b| format!("0x{b:02x}")).collect();
        e.line(&format!("    {},", row.join(", ")));
    }
    e.line("};");
}

/// `static const uint32_t NAME[] = {…};`
pub(crate) fn words(e: &mut Emitter, name: &str, data: &[u32]) {
    e.line(&format!(
        "static const uint32_t {name}[{}] = {{",
        data.len().max(1)
    ));
    if data.is_empty() {
        e.line("    0");
    }
    for chunk in data.chunks(8) {
        let row: Vec<String> = chunk.iter().map(|w| format!("0x{w:08x}")).collect();
        e.line(&format!("    {},", row.join(", ")));
    }
    e.line("};");
}

/// `static const uint32_t NAME[] = {…};` holding `data` as little-endian words (zero-padded to a
/// multiple of 4 bytes): a third of the text of [`bytes`] for large arrays, copied as bytes by a
/// little-endian host.
pub(crate) fn le_words(e: &mut Emitter, name: &str, data: &[u8]) {
    let words: Vec<u32> = data
        .chunks(4)
        .map(|c| {
            let mut b = [0u8; 4];
            b[..c.len()].copy_from_slice(c);
            u32::from_le_bytes(b)
        })
        .collect();
    self::words(e, name, &words);
}

/// A bit mask as a number with its flag names in a comment.
pub(crate) fn flags(bits: u32, names: &[(&str, u64)]) -> String {
    let mut seen = 0u64;
    let mut list = Vec::new();
    for (n, v) in names {
        if *v != 0 && bits as u64 & v == *v && seen & v != *v {
            seen |= v;
            list.push(*n);
        }
    }
    if list.is_empty() {
        format!("0x{bits:x}u")
    } else {
        format!("0x{bits:x}u /* {} */", list.join(" | "))
    }
}

/// The C expression of an address: a literal, or a buffer's device address plus an offset (`buffers`
/// names the world's buffers in their C order). None when the buffer is not one of them.
pub(crate) fn address(a: &Address, buffers: &[String], array: &str) -> Option<String> {
    match a {
        Address::Raw(0) => Some("0".into()),
        Address::Raw(v) => Some(format!("0x{v:x}ull")),
        Address::InBuffer { buffer, offset } => {
            let k = buffers.iter().position(|b| b == buffer)?;
            Some(format!(
                "{array}[{k}].address + {offset}ull /* `{}` */",
                comment_safe(buffer)
            ))
        }
    }
}

/// The bytes of an image with its trailing zeros left out (`write_image` zeroes the buffer first).
pub(crate) fn trimmed(data: &[u8]) -> &[u8] {
    let end = data.iter().rposition(|b| *b != 0).map_or(0, |i| i + 1);
    &data[..end]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strings_and_comments_are_safe_in_c() {
        assert_eq!(string("a\"b\\c\n"), "\"a\\\"b\\\\c\\n\"");
        assert_eq!(string("→"), "\"\\342\\206\\222\"");
        assert_eq!(comment_safe("x */ y"), "x * / y");
        assert_eq!(
            flags(0x3, &[("A", 1), ("B", 2), ("C", 4)]),
            "0x3u /* A | B */"
        );
        assert_eq!(flags(0, &[("A", 1)]), "0x0u");
        assert_eq!(trimmed(&[1, 0, 2, 0, 0]), &[1, 0, 2]);
        let mut e = Emitter::default();
        le_words(&mut e, "w", &[1, 2, 3, 4, 5]);
        assert_eq!(
            e.finish(),
            "static const uint32_t w[2] = {\n    0x04030201, 0x00000005,\n};\n"
        );
        let bufs = vec!["sbt".to_string()];
        assert_eq!(
            address(
                &Address::InBuffer {
                    buffer: "sbt".into(),
                    offset: 32
                },
                &bufs,
                "world"
            )
            .unwrap(),
            "world[0].address + 32ull /* `sbt` */"
        );
        assert_eq!(
            address(&Address::Raw(0x10), &bufs, "world").unwrap(),
            "0x10ull"
        );
        assert!(address(
            &Address::InBuffer {
                buffer: "x".into(),
                offset: 0
            },
            &bufs,
            "world"
        )
        .is_none());
    }
}
