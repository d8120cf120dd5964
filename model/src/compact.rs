//! serde_yaml's block output with every sequence of plain words (numbers, names) written as one flow
//! sequence on its key's line (`min: [-0.5, 1.0, 2.0]`, `- [0.0, 1.0, 0.0]`, `flags: [OPAQUE]`), and
//! every sequence item that is a mapping of such values as one flow mapping (`- {origin: [0.0, 0.0,
//! 4.0], direction: [0.0, 0.0, -1.0], tmin: 0.5, tmax: .inf}`): a rendered scene's coordinates then
//! take a line per vertex or ray instead of four to ten, and reading the file back a fraction of the
//! YAML scanner's work. The value read back is the same; only the layout differs.

/// Whether `s` is a plain scalar serde_yaml writes for a number (decimal, exponent, `.inf`, `.nan`).
pub(crate) fn is_number(s: &str) -> bool {
    matches!(s, ".inf" | "-.inf" | ".nan" | ".NaN" | ".Inf" | "-.Inf")
        || (!s.is_empty()
            && s.trim_start_matches('-')
                .starts_with(|c: char| c.is_ascii_digit())
            && s.chars()
                .all(|c| c.is_ascii_digit() || matches!(c, '-' | '+' | '.' | 'e' | 'E')))
}

/// Whether `s` is a plain scalar that reads the same inside a flow collection: a number, or a name
/// of letters, digits and `_ . + -` that starts with a letter, digit or `_`.
pub(crate) fn is_word(s: &str) -> bool {
    is_number(s)
        || (s.starts_with(|c: char| c.is_ascii_alphanumeric() || c == '_')
            && s.chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '.' | '+' | '-')))
}

/// Whether a line's text ends in a block scalar's header (`key: |-`, `- >`, `|2`).
fn opens_block_scalar(body: &str) -> bool {
    let last = body.rsplit(' ').next().unwrap_or(body);
    let header = last.starts_with(['|', '>'])
        && last.len() <= 3
        && last[1..]
            .chars()
            .all(|c| matches!(c, '+' | '-') || c.is_ascii_digit());
    // What stands before the header: nothing, `KEY: ` or `- ` (tested without building strings: every
    // line of a case file is asked).
    let before = &body[..body.len() - last.len()];
    header && (before.is_empty() || before.ends_with(": ") || before == "- ")
}

/// When line `k` opens a block scalar: it and the scalar's text (its deeper lines) copied as they
/// are, and the line after them.
fn copy_block_scalar(lines: &[&str], k: usize, out: &mut String) -> Option<usize> {
    let at = indent(lines[k]);
    if !opens_block_scalar(&lines[k][at..]) {
        return None;
    }
    let mut next = k;
    while next == k
        || lines
            .get(next)
            .is_some_and(|l| l.trim().is_empty() || indent(l) > at)
    {
        out.push_str(lines[next]);
        out.push('\n');
        next += 1;
    }
    Some(next)
}

fn indent(line: &str) -> usize {
    line.len() - line.trim_start_matches(' ').len()
}

/// The word of a `- WORD` line at exactly `at` columns of indentation.
fn item_at(line: &str, at: usize) -> Option<&str> {
    if indent(line) != at {
        return None;
    }
    let n = line[at..].strip_prefix("- ")?;
    is_word(n).then_some(n)
}

/// The words of the sequence whose items stand at column `at` from line `from` on, and the line
/// after them; None unless every item of that sequence is a word (a following line at column `at`
/// that is another item, or any deeper line, means the sequence holds something else).
fn words_from<'a>(lines: &[&'a str], from: usize, at: usize) -> Option<(Vec<&'a str>, usize)> {
    let mut out = Vec::new();
    let mut k = from;
    while let Some(n) = lines.get(k).and_then(|l| item_at(l, at)) {
        out.push(n);
        k += 1;
    }
    let ends = match lines.get(k) {
        None => true,
        Some(l) => indent(l) < at || (indent(l) == at && !l[at..].starts_with('-')),
    };
    (ends && !out.is_empty()).then_some((out, k))
}

/// `key: VALUE` with a name for key and a word or a flow sequence of words for value.
fn entry(text: &str) -> Option<(&str, &str)> {
    let (key, value) = text.split_once(": ")?;
    let words = |v: &str| {
        v.strip_prefix('[')
            .and_then(|v| v.strip_suffix(']'))
            .is_some_and(|inner| inner.split(", ").all(is_word))
    };
    (is_word(key) && !is_number(key) && (is_word(value) || words(value))).then_some((key, value))
}

/// `yaml` (serde_yaml's block output) with its sequences of words as flow sequences and its
/// sequence items that map names to them as flow mappings.
pub fn compact_yaml(yaml: &str) -> String {
    flow_mappings(&flow_sequences(yaml))
}

/// Each line of `yaml` copied, block scalars whole, except where `at` rewrites the lines from `k`
/// on into `out` and says the line after them.
fn rewrite(yaml: &str, at: impl Fn(&[&str], usize, &mut String) -> Option<usize>) -> String {
    let lines: Vec<&str> = yaml.lines().collect();
    let mut out = String::with_capacity(yaml.len());
    let mut k = 0;
    while k < lines.len() {
        if let Some(next) =
            copy_block_scalar(&lines, k, &mut out).or_else(|| at(&lines, k, &mut out))
        {
            k = next;
            continue;
        }
        out.push_str(lines[k]);
        out.push('\n');
        k += 1;
    }
    out
}

/// `indentation` then `items` joined by `, ` inside `open` and `close`, as one line.
fn flow_line(out: &mut String, indentation: &str, open: &str, items: &[String], close: char) {
    out.push_str(indentation);
    out.push_str(open);
    out.push_str(&items.join(", "));
    out.push(close);
    out.push('\n');
}

/// Each `- KEY: VALUE` item whose further lines are `KEY: VALUE` two columns in, every value a word
/// or a flow sequence of words, as one `- {KEY: VALUE, ...}` line.
fn flow_mappings(yaml: &str) -> String {
    rewrite(yaml, |lines, k, out| {
        let line = lines[k];
        let at = indent(line);
        let first = line[at..].strip_prefix("- ").and_then(entry)?;
        let mut entries = vec![first];
        let mut next = k + 1;
        while let Some(e) = lines
            .get(next)
            .filter(|l| indent(l) == at + 2)
            .and_then(|l| entry(&l[at + 2..]))
        {
            entries.push(e);
            next += 1;
        }
        lines.get(next).is_none_or(|l| indent(l) <= at).then(|| {
            let text: Vec<String> = entries.iter().map(|(k, v)| format!("{k}: {v}")).collect();
            flow_line(out, &line[..at], "- {", &text, '}');
            next
        })
    })
}

/// `yaml` (serde_yaml's block output) with its sequences of words as flow sequences.
fn flow_sequences(yaml: &str) -> String {
    rewrite(yaml, |lines, k, out| {
        let line = lines[k];
        let at = indent(line);
        let body = &line[at..];
        let owned = |words: Vec<&str>| words.into_iter().map(String::from).collect::<Vec<_>>();
        // `KEY:` whose sequence stands at the key's column (serde_yaml writes it unindented), or
        // `- KEY:` with the key two columns in.
        let key_column = if body.starts_with("- ") { at + 2 } else { at };
        if body.ends_with(':') && !body.contains(": ") && !body.starts_with(['"', '\'', '?']) {
            if let Some((words, next)) = words_from(lines, k + 1, key_column) {
                flow_line(out, line, " [", &owned(words), ']');
                return Some(next);
            }
        }
        // `- - WORD` opening a sequence of words inside a sequence, its other items two columns in.
        let first = body.strip_prefix("- - ").filter(|n| is_word(n))?;
        let (mut words, next) = words_from(lines, k + 1, at + 2).or(
            // A one-word inner sequence: the next line leaves the column.
            match lines.get(k + 1) {
                None => Some((Vec::new(), k + 1)),
                Some(l) if indent(l) <= at => Some((Vec::new(), k + 1)),
                _ => None,
            },
        )?;
        words.insert(0, first);
        flow_line(out, &line[..at], "- [", &owned(words), ']');
        Some(next)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_become_flow_collections_and_read_back_the_same() {
        let value: serde_yaml::Value = serde_yaml::from_str(
            "a:\n  positions: [[1.0, -2.5, .nan], [0.0, 1e-30, -.inf], [7.0]]\n  boxes:\n  - min: [-0.5, 1, 2]\n    max: [1.5, 2, 3]\n    name: x\n  words: [1, 2, 3]\n  mixed: [1, two, 3]\n  spaced: [a b, c]\n  items: [{name: y, deep: {k: 1}}]\n  nested: [[1, 2], [a, 3]]\n  text: \"- 1\"\n  empty: []\n",
        )
        .unwrap();
        let block = serde_yaml::to_string(&value).unwrap();
        let flow = compact_yaml(&block);
        assert!(flow.contains("- [1.0, -2.5, .nan]"), "{flow}");
        assert!(flow.contains("- [7.0]"), "{flow}");
        assert!(
            flow.contains("- {min: [-0.5, 1, 2], max: [1.5, 2, 3], name: x}"),
            "{flow}"
        );
        assert!(flow.contains("words: [1, 2, 3]"), "{flow}");
        assert!(flow.contains("mixed: [1, two, 3]"), "{flow}");
        // Sequences and mappings holding anything but words stay as they were.
        assert!(flow.contains("spaced:\n  - a b\n  - c"), "{flow}");
        assert!(flow.contains("- name: y\n    deep:\n      k: 1"), "{flow}");
        assert!(flow.lines().count() < block.lines().count());
        // Text in a block scalar is never touched.
        let literal = "note: |-\n  k:\n  - 1\n  - a: 2\n    b: 3\nwords:\n- 1\n";
        assert_eq!(
            compact_yaml(literal),
            "note: |-\n  k:\n  - 1\n  - a: 2\n    b: 3\nwords: [1]\n"
        );
        let back: serde_yaml::Value = serde_yaml::from_str(&flow).unwrap();
        // NaN is not equal to itself: compare the two texts' values through their YAML again.
        assert_eq!(serde_yaml::to_string(&back).unwrap(), block);
    }

    #[test]
    fn a_case_file_reads_back_as_the_same_case() {
        let mut read = 0;
        for path in crate::test_cases::repository_case_files() {
            let text = std::fs::read_to_string(&path).unwrap();
            let Ok(case) = crate::Case::from_yaml("c", &text) else {
                continue;
            };
            let block = serde_yaml::to_string(&case).unwrap();
            let flow = compact_yaml(&block);
            let back = crate::Case::from_yaml("c", &flow).unwrap_or_else(|e| {
                panic!("{}: {e}\n{flow}", path.display());
            });
            assert_eq!(
                serde_yaml::to_string(&back).unwrap(),
                block,
                "{}",
                path.display()
            );
            read += 1;
        }
        assert!(read >= 20, "only {read} case files read");
    }
}
