//! Resident-set size of a process, read from `/proc/self/status` or `/proc/PID/status`
//! (Linux), so that a soak can show that memory does not grow.

use std::path::PathBuf;

use thiserror::Error;

/// Why the resident set could not be read.
#[derive(Debug, Error)]
pub enum RssError {
    #[error("cannot read {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path} has no parsable VmRSS line")]
    Missing { path: PathBuf },
}

/// VmRSS in KiB of process `pid`, or of this process when `None`.
pub fn rss_kb(pid: Option<u32>) -> Result<u64, RssError> {
    let path = match pid {
        Some(p) => PathBuf::from(format!("/proc/{p}/status")),
        None => PathBuf::from("/proc/self/status"),
    };
    let text = std::fs::read_to_string(&path)
        .map_err(|source| RssError::Io { path: path.clone(), source })?;
    parse_vm_rss(&text).ok_or(RssError::Missing { path })
}

/// The value of the `VmRSS:` line of a status file, in KiB.
pub fn parse_vm_rss(status: &str) -> Option<u64> {
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    let mut fields = line.split_whitespace().skip(1);
    let value = fields.next()?.parse::<u64>().ok()?;
    match fields.next() {
        Some("kB") | None => Some(value),
        Some(_) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_vm_rss_line_only() {
        let status = "Name:\tx\nVmPeak:\t 999 kB\nVmRSS:\t   1234 kB\nRssAnon:\t 5 kB\n";
        assert_eq!(parse_vm_rss(status), Some(1234));
        assert_eq!(parse_vm_rss("VmRSS: lots kB\n"), None);
        assert_eq!(parse_vm_rss("Name: x\n"), None);
    }

    #[test]
    fn this_process_has_a_resident_set_and_a_missing_one_is_an_error() {
        assert!(rss_kb(None).expect("own status") > 0);
        assert!(rss_kb(Some(std::process::id())).expect("own pid") > 0);
        let err = rss_kb(Some(u32::MAX)).expect_err("no such process");
        assert!(err.to_string().contains("/proc/4294967295/status"), "{err}");
    }
}
