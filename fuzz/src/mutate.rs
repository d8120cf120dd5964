//! Deterministic structured mutations of parser inputs for the short run in `cargo test`: truncation,
//! byte flips, duplicated, removed and swapped lines, huge and edge numbers, deep nesting, repeated
//! chunks, format tokens and splices of two seeds — the same sequence for the same seed, every time.

use crate::Target;

/// A small deterministic generator (SplitMix64).
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// A value in `0..n` (0 when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next_u64() % n as u64) as usize
        }
    }

    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// Numbers that sit on an edge: overflow a u32, u64 or i64, go negative, exponent forms, NaN.
const EDGE_NUMBERS: &[&str] = &[
    "0",
    "-1",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "18446744073709551616",
    "9223372036854775807",
    "-9223372036854775808",
    "100000000000",
    "99999999999999999999999999999999",
    "1e308",
    "1e999",
    "-0",
    "0x",
    "0xffffffffffffffff",
    "0x1ffffffffffffffff",
    ".nan",
    "~0U",
];

/// Tokens of each input format that mutations insert.
fn tokens(target: Target) -> &'static [&'static str] {
    match target {
        Target::VkXml => &[
            "<",
            ">",
            "</",
            "/>",
            "<![CDATA[",
            "]]>",
            "<!--",
            "-->",
            "&amp;",
            "&#x110000;",
            "&#0;",
            "&bogus;",
            "\"",
            " depends=\"(((\"",
            " bitpos=\"64\"",
            " offset=\"4294967295\"",
            " extnumber=\"-1\"",
            " dir=\"-\"",
            " value=\"(~0ULL)\"",
            " alias=\"VK_TOY_ALL\"",
            " extends=\"VkResult\"",
            "<enum name=\"X\" alias=\"X\"/>",
            "<type category=\"struct\" name=\"S\" alias=\"S\"/>",
            "<member><type>uint32_t</type> <name>m</name>[</member>",
            "<?xml version=\"1.0\"?>",
            "<!DOCTYPE registry [<!ENTITY e \"x\">]>",
        ],
        Target::Validusage => &[
            "{",
            "}",
            "[",
            "]",
            ",",
            ":",
            "\"",
            "\\u0000",
            "\\ud800",
            "\\",
            "null",
            "true",
            "\"core\"",
            "\"(\"",
            "\"!\"",
            "\"VUID-\"",
            "\"condition\":\"((\"",
            "&lt;",
            "&#99999999;",
            "<strong>",
            "</a>",
        ],
        Target::ManpageMarkdown | Target::ManpagePandoc | Target::ManpagePlain => &[
            "- [](#VUID-",
            "- [](#VUID-vkCmdToyDispatch-x-1)",
            "- <a ",
            "- <a id=\"VUID-",
            "id='VUID-a-b-1",
            "</a>",
            "VUID-",
            "VUID-vkCmdToyDispatch-stride-00001",
            "VUID-a-b-c-d",
            "```",
            ");",
            "(",
            "typedef struct vkCmdToyDispatch {",
            "} vkCmdToyDispatch;",
            "void vkCmdToyDispatch(",
            "\t",
            "\r",
            "  ",
            "# ",
            "Valid Usage",
            "See Also",
            "**must**",
            "&amp;",
            "\u{2019}",
            "\u{feff}",
        ],
        Target::TraceCase | Target::BuildCase | Target::Triage => &[
            "- ",
            ": ",
            "[",
            "]",
            "{",
            "}",
            "!violates",
            "!valid",
            "!floats",
            "!ranges",
            "!instances",
            "!pointers",
            "!aabbs",
            "!triangles",
            "!shader-records",
            "!trace-rays-indirect-command",
            "command: vkCmdTraceRaysNV\n",
            "command: vkCmdTraceRaysKHR\n",
            "command: vkCmdBuildAccelerationStructuresIndirectKHR\n",
            "&a ",
            "*a",
            "<<: *a",
            "---\n",
            "...\n",
            "? ",
            "|\n",
            ">-\n",
            "\"\\u",
            "'",
            "~",
            "null",
            "\t",
            "*",
            "**",
            "?*",
        ],
        Target::DeviceProfile => &[
            "{",
            "}",
            "[",
            "]",
            ",",
            ":",
            "\"",
            "null",
            "true",
            "\"capabilities\":{}",
            "\"properties\":{\"S\":{\"m\":[[[[1]]]]}}",
            "\"api-version\":\"4294967296.99999999999.1\"",
            "\"maxShaderGroupStride\":18446744073709551615",
            "\"shaderGroupHandleSize\":0",
            "\"shaderGroupBaseAlignment\":0",
        ],
        Target::Baseline => &[
            ",", ",fail", ",crash", ",timeout", ",pass", "*", "**", "#", "VUID-", " ", "\t", "\r",
            "\n", "\u{feff}",
        ],
        Target::CasePatterns => &[
            "(", ")", "[", "]", "{", "}", "*", "+", "?", "^", "$", "\\", "|", "{1000}", "{0,}",
            "(?i)", "(?x)", "\\p{L}", "\\b", ".", "#", "\n",
        ],
    }
}

/// The opener repeated to nest an input deeply, and a matching closer (possibly empty).
fn nesting(target: Target, rng: &mut Rng) -> (&'static str, &'static str) {
    let choices: &[(&str, &str)] = match target {
        Target::VkXml => &[("<a>", "</a>"), ("<type>", ""), ("(", "")],
        Target::Validusage | Target::DeviceProfile => {
            &[("[", "]"), ("{\"a\":", "}"), ("(", ""), ("!", "")]
        }
        Target::ManpageMarkdown | Target::ManpagePandoc | Target::ManpagePlain => {
            &[("  - ", ""), ("(", ")"), ("<a ", "</a>"), ("**", "")]
        }
        Target::TraceCase | Target::BuildCase | Target::Triage => {
            &[("[", "]"), ("{a: ", "}"), ("- ", ""), ("*", "")]
        }
        Target::Baseline => &[("*", ""), ("a*", "")],
        Target::CasePatterns => &[("(", ")"), ("[", "]"), ("(?:a|", ")"), ("a{2}", "")],
    };
    *rng.pick(choices)
}

/// One mutation of `input`; `other` is another seed of the same target, for splices.
pub fn mutate_once(target: Target, input: &[u8], other: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut out = input.to_vec();
    match rng.below(14) {
        // truncate
        0 => out.truncate(rng.below(out.len() + 1)),
        // flip a bit
        1 => {
            if !out.is_empty() {
                let i = rng.below(out.len());
                out[i] ^= 1 << rng.below(8);
            }
        }
        // overwrite a byte with a structural one
        2 => {
            if !out.is_empty() {
                let i = rng.below(out.len());
                out[i] = *rng.pick(b"\0\n\r\t <>\"'{}[]:-,&*!()#`|\\~");
            }
        }
        // duplicate, remove or swap lines
        3..=5 => {
            let mut lines: Vec<Vec<u8>> = out.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect();
            let i = rng.below(lines.len());
            let j = rng.below(lines.len());
            match rng.below(3) {
                0 => {
                    let l = lines[i].clone();
                    lines.insert(j, l);
                }
                1 => {
                    lines.remove(i);
                }
                _ => lines.swap(i, j),
            }
            out = lines.join(&b'\n');
        }
        // replace a run of digits with an edge number
        6 => {
            let runs = digit_runs(&out);
            if !runs.is_empty() {
                let (s, e) = *rng.pick(&runs);
                let n = rng.pick(EDGE_NUMBERS).as_bytes();
                out.splice(s..e, n.iter().copied());
            }
        }
        // every number of one line becomes the same edge number (a size with its offset, a
        // stride with its count)
        12 | 13 => {
            let lines: Vec<(usize, usize)> = line_spans(&out);
            let (ls, le) = *rng.pick(&lines);
            let n = rng.pick(EDGE_NUMBERS).as_bytes();
            let runs = digit_runs(&out[ls..le]);
            for &(s, e) in runs.iter().rev() {
                out.splice(ls + s..ls + e, n.iter().copied());
            }
        }
        // deep nesting at a random place
        7 => {
            let (open, close) = nesting(target, rng);
            // 10,000 levels overflow any unguarded recursion of the parsers (tests run on 2 MiB
            // stacks); deeper would only slow the short run (libyaml scans flow levels quadratically)
            let depth = [65, 200, 1_000, 10_000][rng.below(4)];
            let at = rng.below(out.len() + 1);
            let mut ins = open.repeat(depth).into_bytes();
            if rng.below(2) == 0 {
                ins.extend(close.repeat(depth).bytes());
            }
            out.splice(at..at, ins);
        }
        // a token of the format
        8 => {
            let t = rng.pick(tokens(target)).as_bytes();
            let at = rng.below(out.len() + 1);
            out.splice(at..at, t.iter().copied());
        }
        // splice with another seed
        9 => {
            let a = rng.below(out.len() + 1);
            let b = rng.below(other.len() + 1);
            out.truncate(a);
            out.extend_from_slice(&other[b..]);
        }
        // repeat a chunk many times
        10 => {
            if !out.is_empty() {
                let s = rng.below(out.len());
                let e = (s + 1 + rng.below(64)).min(out.len());
                let chunk = out[s..e].to_vec();
                let times = [2, 16, 500, 5_000][rng.below(4)];
                let ins: Vec<u8> = chunk.repeat(times);
                out.splice(e..e, ins);
            }
        }
        // delete a range
        _ => {
            if !out.is_empty() {
                let s = rng.below(out.len());
                let e = (s + 1 + rng.below(256)).min(out.len());
                out.drain(s..e);
            }
        }
    }
    out
}

/// The longest mutated input of a target. The YAML readers' scanner takes time quadratic in the
/// nesting of flow collections on one line (a recorded finding, fuzz/README.md), and each line of a
/// skips or flakes file is compiled as a regular expression: longer inputs would only spend the short
/// run's time there. Deep nesting (10,000 levels) still fits.
pub fn max_len(target: Target) -> usize {
    match target {
        Target::TraceCase | Target::BuildCase | Target::Triage | Target::CasePatterns => 48 << 10,
        _ => 256 << 10,
    }
}

/// One to three stacked mutations, cut to [`max_len`].
pub fn mutate(target: Target, input: &[u8], other: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut out = mutate_once(target, input, other, rng);
    for _ in 0..rng.below(3) {
        out = mutate_once(target, &out, other, rng);
    }
    out.truncate(max_len(target));
    out
}

/// `[start, end)` of every line (without its newline); one empty span for an empty input.
fn line_spans(b: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut start = 0;
    for (i, &c) in b.iter().enumerate() {
        if c == b'\n' {
            spans.push((start, i));
            start = i + 1;
        }
    }
    spans.push((start, b.len()));
    spans
}

fn digit_runs(b: &[u8]) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i].is_ascii_digit() {
            let s = i;
            while i < b.len() && b[i].is_ascii_digit() {
                i += 1;
            }
            runs.push((s, i));
        } else {
            i += 1;
        }
    }
    runs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_seed_gives_the_same_mutations() {
        let input = b"a: 1\nb: [2, 3]\n";
        let run = |seed| {
            let mut rng = Rng::new(seed);
            (0..50)
                .map(|_| mutate(Target::TraceCase, input, b"c: 4\n", &mut rng))
                .collect::<Vec<_>>()
        };
        assert_eq!(run(7), run(7));
        assert_ne!(run(7), run(8));
    }

    #[test]
    fn edge_numbers_replace_whole_digit_runs() {
        assert_eq!(digit_runs(b"a12b3"), vec![(1, 3), (4, 5)]);
        assert_eq!(line_spans(b"ab\n\nc"), vec![(0, 2), (3, 3), (4, 5)]);
    }
}
