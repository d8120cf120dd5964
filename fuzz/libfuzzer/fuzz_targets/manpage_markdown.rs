//! libFuzzer binary for the `manpage_markdown` target of rtconf-fuzz.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| rtconf_fuzz::fuzz_one(rtconf_fuzz::Target::ManpageMarkdown, data));
