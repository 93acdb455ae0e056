//! CPU time as Linux accounts it: the whole machine from `/proc/stat`, this process from
//! `/proc/self/stat`, both in clock ticks (`USER_HZ`), so the owner's share is their
//! difference (`decide` turns two samples into a fraction).
//!
//! Parsing is separate from reading so that tests feed recorded text.

use super::IdleError;

/// Cumulative CPU times at one instant, in clock ticks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CpuTimes {
    /// All time of all CPUs (user + nice + system + idle + iowait + irq + softirq + steal).
    pub total: u64,
    /// The part not idle (total − idle − iowait): every process's, this one's included.
    pub busy: u64,
    /// This process's user + system time, all its threads.
    pub own: u64,
}

/// Parses the aggregate `cpu` line of `/proc/stat` into (total, busy).
pub fn parse_proc_stat(text: &str) -> Result<(u64, u64), IdleError> {
    let line = text
        .lines()
        .find(|l| l.starts_with("cpu "))
        .ok_or_else(|| IdleError::Parse("/proc/stat has no aggregate `cpu` line".into()))?;
    let fields: Vec<u64> = line
        .split_whitespace()
        .skip(1)
        .map(|f| f.parse::<u64>())
        .collect::<Result<_, _>>()
        .map_err(|e| IdleError::Parse(format!("/proc/stat `cpu` line: {e}")))?;
    if fields.len() < 4 {
        return Err(IdleError::Parse(format!(
            "/proc/stat `cpu` line has {} fields, expected at least 4",
            fields.len()
        )));
    }
    // user nice system idle iowait irq softirq steal [guest guest_nice]: guest time is
    // already inside user and nice, so only the first eight add up to the total.
    let total: u64 = fields.iter().take(8).sum();
    let idle = fields[3] + fields.get(4).copied().unwrap_or(0);
    Ok((total, total.saturating_sub(idle)))
}

/// Parses `/proc/<pid>/stat` into the process's utime + stime.
pub fn parse_self_stat(text: &str) -> Result<u64, IdleError> {
    // The command name (field 2) is in parentheses and may hold spaces or ')'; the
    // fields after the last ')' start with field 3 (state): utime and stime are 14, 15.
    let rest = text
        .rfind(')')
        .map(|i| &text[i + 1..])
        .ok_or_else(|| IdleError::Parse("/proc/self/stat has no `(comm)` field".into()))?;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let field = |i: usize, name: &str| -> Result<u64, IdleError> {
        fields
            .get(i)
            .ok_or_else(|| IdleError::Parse(format!("/proc/self/stat has no {name} field")))?
            .parse::<u64>()
            .map_err(|e| IdleError::Parse(format!("/proc/self/stat {name}: {e}")))
    };
    Ok(field(11, "utime")? + field(12, "stime")?)
}

/// Reads both files now.
pub fn read() -> Result<CpuTimes, IdleError> {
    let read = |path: &str| {
        std::fs::read_to_string(path).map_err(|e| IdleError::Read(format!("{path}: {e}")))
    };
    let (total, busy) = parse_proc_stat(&read("/proc/stat")?)?;
    let own = parse_self_stat(&read("/proc/self/stat")?)?;
    Ok(CpuTimes { total, busy, own })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_aggregate_line_gives_total_and_busy_time() {
        let text = "cpu  79724 0 5572 8696 243 0 70 25 0 0\ncpu0 39478 0 2713 4863 98 0 6 11 0 0\n";
        let (total, busy) = parse_proc_stat(text).unwrap();
        assert_eq!(total, 79724 + 5572 + 8696 + 243 + 70 + 25);
        assert_eq!(busy, total - 8696 - 243);
    }

    #[test]
    fn a_command_name_with_spaces_and_parentheses_does_not_shift_the_fields() {
        let text = "4242 (my (odd) cmd) R 1 1 1 0 -1 4194304 101 0 0 0 250 31 0 0 20 0 3 0 47420";
        assert_eq!(parse_self_stat(text).unwrap(), 281);
    }

    #[test]
    fn malformed_files_are_errors_that_name_the_file() {
        let err = parse_proc_stat("intr 1 2 3").unwrap_err().to_string();
        assert!(err.contains("/proc/stat"), "{err}");
        let err = parse_self_stat("4242 (x) R 1").unwrap_err().to_string();
        assert!(err.contains("utime"), "{err}");
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn this_machine_and_process_can_be_read() {
        let a = read().unwrap();
        assert!(a.total > 0 && a.busy <= a.total, "{a:?}");
    }
}
