//! The peak memory of a stage. Linux keeps a process's high-water mark of resident memory
//! (`VmHWM` in `/proc/self/status`) and lets a process reset it (`5` into
//! `/proc/self/clear_refs`), so each stage's peak is measured from its start. Elsewhere there
//! is no figure, and the report says so.

/// Starts a new high-water mark at the memory resident now.
pub fn reset_peak() {
    // Without /proc (not Linux) there is nothing to reset and `peak_bytes` says None.
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// The most memory resident since the last [`reset_peak`] (or since the process started).
pub fn peak_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    parse_hwm(&status)
}

/// `VmHWM:    13520 kB` in bytes.
fn parse_hwm(status: &str) -> Option<u64> {
    kb_field(status, "VmHWM:")
}

/// The line `key   N kB` of a `/proc` file (`status`, `meminfo`), in bytes.
pub(crate) fn kb_field(text: &str, key: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(key))?;
    let kb: u64 = line[key.len()..]
        .trim()
        .strip_suffix("kB")?
        .trim()
        .parse()
        .ok()?;
    Some(kb * 1024)
}

#[cfg(test)]
mod tests {
    #[test]
    fn reads_the_high_water_mark_line() {
        let status = "Name:\tcrowd\nVmPeak:\t  20000 kB\nVmHWM:\t   13520 kB\nVmRSS:\t 9000 kB\n";
        assert_eq!(super::parse_hwm(status), Some(13520 * 1024));
        assert_eq!(super::parse_hwm("VmRSS:\t 9000 kB\n"), None);
    }

    #[test]
    fn a_stage_that_allocates_raises_the_peak() {
        super::reset_peak();
        let Some(before) = super::peak_bytes() else {
            return; // not Linux: no figure to check
        };
        // Touched page by page, and kept from the optimiser, so that it is resident.
        let mut big = std::hint::black_box(vec![0u8; 64 << 20]);
        for page in big.chunks_mut(4096) {
            page[0] = 1;
        }
        std::hint::black_box(&big);
        let after = super::peak_bytes().unwrap();
        assert!(after >= before + (60 << 20), "{before} -> {after}");
    }
}
