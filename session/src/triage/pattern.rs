//! Patterns of triage entries: a VUID, case name or output key in which `*` stands for any run of
//! characters (`VUID-vkCmdTraceRays*KHR-None-03429` covers the direct and the indirect command).

/// A text with `*` wildcards.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, serde::Deserialize)]
#[serde(transparent)]
pub struct Pattern(String);

impl std::fmt::Display for Pattern {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl Pattern {
    pub fn new(text: impl Into<String>) -> Pattern {
        Pattern(text.into())
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// Whether `text` matches the whole pattern.
    pub fn matches(&self, text: &str) -> bool {
        self.captures(text).is_some()
    }

    /// The runs of `text` each `*` stands for, left to right (the leftmost, shortest runs that make the
    /// rest match), or None when `text` does not match.
    pub fn captures<'t>(&self, text: &'t str) -> Option<Vec<&'t str>> {
        let parts: Vec<&str> = self.0.split('*').collect();
        let first = parts[0];
        let mut rest = text.strip_prefix(first)?;
        let mut caps = Vec::new();
        if parts.len() == 1 {
            return rest.is_empty().then_some(caps);
        }
        for (i, part) in parts.iter().enumerate().skip(1) {
            if i == parts.len() - 1 {
                let cut = rest.len().checked_sub(part.len())?;
                if !rest.is_char_boundary(cut) || &rest[cut..] != *part {
                    return None;
                }
                caps.push(&rest[..cut]);
                return Some(caps);
            }
            let at = rest.find(part)?;
            caps.push(&rest[..at]);
            rest = &rest[at + part.len()..];
        }
        Some(caps)
    }

    /// Whether the pattern has no wildcard.
    pub fn is_literal(&self) -> bool {
        !self.0.contains('*')
    }
}

#[cfg(test)]
mod tests {
    use super::Pattern;

    #[test]
    fn patterns_match_both_trace_commands_and_nothing_else() {
        let p = Pattern::new("VUID-vkCmdTraceRays*KHR-None-03429");
        assert!(p.matches("VUID-vkCmdTraceRaysKHR-None-03429"));
        assert!(p.matches("VUID-vkCmdTraceRaysIndirectKHR-None-03429"));
        assert!(!p.matches("VUID-vkCmdTraceRaysNV-None-03429"));
        assert!(!p.matches("VUID-vkCmdTraceRaysKHR-None-034290"));
        assert!(Pattern::new("VUID-x").matches("VUID-x"));
        assert!(!Pattern::new("VUID-x").matches("VUID-xy"));
        assert!(Pattern::new("*").matches(""));
    }

    #[test]
    fn captures_are_the_runs_the_stars_stand_for() {
        let p = Pattern::new("VUID-vkCmdTraceRays*KHR-*");
        assert_eq!(
            p.captures("VUID-vkCmdTraceRaysIndirectKHR-None-02691"),
            Some(vec!["Indirect", "None-02691"])
        );
        assert_eq!(
            p.captures("VUID-vkCmdTraceRaysKHR-None-02691"),
            Some(vec!["", "None-02691"])
        );
        assert_eq!(p.captures("VUID-vkCmdTraceRaysNV-None-02691"), None);
    }
}
