//! libFuzzer binary for the `baseline` target of rtconf-fuzz.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| rtconf_fuzz::fuzz_one(rtconf_fuzz::Target::Baseline, data));
