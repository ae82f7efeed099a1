//! UTC timestamps for report names, dates and reports' `started`/`finished` (RFC 3339), from the
//! system clock (no time-zone database).

/// `YYYY-MM-DD` of a Unix time (days-from-civil inverse, Howard Hinnant's algorithm).
pub fn civil_date(unix_secs: u64) -> String {
    let (y, m, d) = ymd(unix_secs);
    format!("{y:04}-{m:02}-{d:02}")
}

/// `YYYYMMDD-HHMMSS` of a Unix time, for file names.
pub fn stamp(unix_secs: u64) -> String {
    let (y, m, d) = ymd(unix_secs);
    let s = unix_secs % 86_400;
    format!("{y:04}{m:02}{d:02}-{:02}{:02}{:02}", s / 3600, (s / 60) % 60, s % 60)
}

/// RFC 3339 (`YYYY-MM-DDTHH:MM:SSZ`, UTC) of a Unix time, for JSON.
pub fn rfc3339(unix_secs: u64) -> String {
    let s = unix_secs % 86_400;
    format!("{}T{:02}:{:02}:{:02}Z", civil_date(unix_secs), s / 3600, (s / 60) % 60, s % 60)
}

fn ymd(unix_secs: u64) -> (i64, u32, u32) {
    let z = (unix_secs / 86_400) as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let y = yoe + era * 400 + i64::from(m <= 2);
    (y, m, d)
}

pub fn now_unix() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_dates() {
        assert_eq!(civil_date(0), "1970-01-01");
        assert_eq!(civil_date(1_795_000_000), "2026-11-18");
        assert_eq!(stamp(1_795_000_000), "20261118-110640");
        assert_eq!(civil_date(951_782_400), "2000-02-29");
        assert_eq!(rfc3339(1_795_000_000), "2026-11-18T11:06:40Z");
        assert_eq!(rfc3339(0), "1970-01-01T00:00:00Z");
    }
}
