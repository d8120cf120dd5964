//! libFuzzer binary for the `case_patterns` target of rtconf-fuzz.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| rtconf_fuzz::fuzz_one(rtconf_fuzz::Target::CasePatterns, data));
