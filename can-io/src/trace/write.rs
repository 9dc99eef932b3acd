//! Writers of the text trace formats (`dnet-master --log FILE --format F`): candump `-L`, PCAN
//! `.trc` 2.1, Vector `.asc` and CSV (python-can's layout, see [`super::csv`]).
//!
//! Every line goes through a buffer; [`TraceWriter::flush`] empties it, so a recording flushed after
//! each frame keeps every line written before an interruption. [`TraceWriter::finish`] writes the
//! format's footer (ASC's `End TriggerBlock`) and flushes; it is idempotent and also done, best
//! effort, when the writer is dropped.
//!
//! ## Times
//!
//! A frame's [`Instant`] is written as it is, as the time from the start of the recording: the bus
//! clock's origin is the moment the bus was opened, which is what trc's time offsets and asc's
//! `timestamps absolute` count from. The header's wall-clock start (trc `;$STARTTIME` and
//! `Start time:`, asc `date` and `Begin Triggerblock`) is the time the writer was created
//! ([`TraceWriter::new`]) or the one given to [`TraceWriter::with_start_time`]; candump and CSV
//! lines carry the bus time only.
//!
//! ## Channels and directions
//!
//! trc and asc number their channels: an interface named by a number 1..=255 keeps it, any other
//! (`sim`, `can0`) is written as channel 1. A frame written without a direction is written as `Rx`
//! in trc and asc (both require one); candump and CSV do not record directions.

use super::entry::format_line;
use super::{Direction, TraceFormat};
use base64::Engine as _;
use devicenet::{CanFrame, Instant};
use std::fmt::Write as _;
use std::io::{self, BufWriter, Write};
use std::path::Path;
use std::time::{SystemTime, UNIX_EPOCH};

/// Writes frames into a text trace of one format.
pub struct TraceWriter {
    out: BufWriter<Box<dyn Write>>,
    format: TraceFormat,
    /// Frames written so far (trc's message numbers).
    count: u64,
    finished: bool,
}

impl std::fmt::Debug for TraceWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TraceWriter").field("format", &self.format).field("count", &self.count).finish()
    }
}

impl TraceWriter {
    /// A writer of `format` into `out`, its header written now with the current wall-clock time;
    /// an error for a format that is not written ([`TraceFormat::writable`]).
    pub fn new(out: Box<dyn Write>, format: TraceFormat) -> io::Result<TraceWriter> {
        TraceWriter::with_start_time(out, format, SystemTime::now())
    }

    /// As [`TraceWriter::new`], with the header's wall-clock start time given (reproducible files).
    pub fn with_start_time(
        out: Box<dyn Write>,
        format: TraceFormat,
        start: SystemTime,
    ) -> io::Result<TraceWriter> {
        if !format.writable() {
            return Err(not_written(format));
        }
        let mut writer = TraceWriter { out: BufWriter::new(out), format, count: 0, finished: false };
        let start = Civil::from(start);
        let header = match format {
            TraceFormat::Trc => trc_header(&start),
            TraceFormat::Asc => {
                let date = start.asc_date();
                format!(
                    "date {date}\nbase hex  timestamps absolute\ninternal events logged\n\
                     Begin Triggerblock {date}\n   0.000000 Start of measurement\n"
                )
            }
            TraceFormat::Csv => "timestamp,arbitration_id,extended,remote,error,dlc,data\n".to_string(),
            _ => String::new(),
        };
        writer.out.write_all(header.as_bytes())?;
        Ok(writer)
    }

    /// A `candump -L` writer (no header, so nothing can fail yet).
    pub fn candump(out: Box<dyn Write>) -> TraceWriter {
        TraceWriter { out: BufWriter::new(out), format: TraceFormat::Candump, count: 0, finished: false }
    }

    /// The format written.
    pub fn format(&self) -> TraceFormat {
        self.format
    }

    /// Appends one frame.
    pub fn write(
        &mut self,
        at: Instant,
        iface: &str,
        direction: Option<Direction>,
        frame: &CanFrame,
    ) -> io::Result<()> {
        self.count += 1;
        let us = at.total_micros();
        let dir = direction.unwrap_or(Direction::Rx).name();
        let mut line = String::with_capacity(80);
        // Writing into a String cannot fail.
        let _ = match self.format {
            TraceFormat::Trc => {
                let time = format!("{}.{:03}", us / 1000, us % 1000);
                let id = format!("{:04X}", frame.id().as_raw());
                write!(
                    line,
                    "{:>7} {time:>13} DT {:>2} {id:>8} {dir} -  {:<4} {}",
                    self.count,
                    channel(iface),
                    frame.dlc(),
                    hex(frame)
                )
            }
            TraceFormat::Asc => {
                let time = format!("{}.{:06}", us / 1_000_000, us % 1_000_000);
                let id = format!("{:X}", frame.id().as_raw());
                write!(
                    line,
                    "{time:>11} {}  {id:<15} {dir:<4} d {} {}",
                    channel(iface),
                    frame.dlc(),
                    hex(frame)
                )
            }
            TraceFormat::Csv => write!(
                line,
                "{}.{:06},0x{:x},0,0,0,{},{}",
                us / 1_000_000,
                us % 1_000_000,
                frame.id().as_raw(),
                frame.dlc(),
                base64::engine::general_purpose::STANDARD.encode(frame.data())
            ),
            _ => write!(line, "{}", format_line(at, iface, frame)),
        };
        let line = line.trim_end();
        self.out.write_all(line.as_bytes())?;
        self.out.write_all(self.newline())
    }

    /// Writes out what is buffered.
    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }

    /// Writes the footer (ASC's `End TriggerBlock`) and flushes; later calls do nothing.
    pub fn finish(&mut self) -> io::Result<()> {
        if self.finished {
            return Ok(());
        }
        self.finished = true;
        if self.format == TraceFormat::Asc {
            self.out.write_all(b"End TriggerBlock\n")?;
        }
        self.out.flush()
    }

    /// PEAK's trc lines end in CR LF; the others in LF.
    fn newline(&self) -> &'static [u8] {
        if self.format == TraceFormat::Trc {
            b"\r\n"
        } else {
            b"\n"
        }
    }
}

impl Drop for TraceWriter {
    fn drop(&mut self) {
        let _ = self.finish();
    }
}

/// Why a `--log FILE` cannot be written in the format asked for, or the one its name implies.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LogFormatError {
    /// `--format` names a format that is read but not written.
    #[error("--format {0}: --log writes candump, trc, asc or csv")]
    Given(TraceFormat),
    /// The file's extension names a format that is read but not written.
    #[error(
        "--log {path}: the extension names {format}, which --log does not write (it writes candump, trc, asc or csv); give --format FORMAT to write one of those under this name"
    )]
    Extension {
        /// The file.
        path: String,
        /// The format its extension names.
        format: TraceFormat,
    },
}

/// The format `--log FILE` is written in, the same for every program with `--log`: `given`
/// (`--format`), else the format FILE's extension names ([`TraceFormat::from_extension`]:
/// `.asc`, `.trc`, `.csv`; `.log` and `.candump` are candump), else candump.
///
/// # Errors
///
/// `given`, or the extension when nothing is given, names a format that is not written
/// ([`TraceFormat::writable`]): a `.pcap`, `.pcapng` or `.blf` name with no `--format`.
pub fn log_format(path: &Path, given: Option<TraceFormat>) -> Result<TraceFormat, LogFormatError> {
    match given {
        Some(f) if f.writable() => Ok(f),
        Some(f) => Err(LogFormatError::Given(f)),
        None => match TraceFormat::from_extension(path) {
            None => Ok(TraceFormat::Candump),
            Some(f) if f.writable() => Ok(f),
            Some(format) => Err(LogFormatError::Extension { path: path.display().to_string(), format }),
        },
    }
}

/// The error for a format that is read but not written.
pub(crate) fn not_written(format: TraceFormat) -> io::Error {
    io::Error::new(
        io::ErrorKind::Unsupported,
        format!("{format} traces are read, not written (candump, trc, asc or csv)"),
    )
}

/// The channel number of an interface (see the module docs).
fn channel(iface: &str) -> u8 {
    iface.parse::<u8>().ok().filter(|&c| c >= 1).unwrap_or(1)
}

/// `00 CB 00`.
fn hex(frame: &CanFrame) -> String {
    let mut text = String::with_capacity(24);
    for (i, b) in frame.data().iter().enumerate() {
        let _ = write!(text, "{}{b:02X}", if i == 0 { "" } else { " " });
    }
    text
}

/// trc 2.1's header, as PEAK's example of the version lays it out.
fn trc_header(start: &Civil) -> String {
    let lines = [
        ";$FILEVERSION=2.1".to_string(),
        format!(";$STARTTIME={:.10}", start.ole_days()),
        ";$COLUMNS=N,O,T,B,I,d,R,L,D".to_string(),
        ";".to_string(),
        format!(";   Start time: {}", start.peak_date()),
        ";   Generated by serial-devicenet dnet-master".to_string(),
        ";-------------------------------------------------------------------------------".to_string(),
        ";   Message   Time    Type    ID     Rx/Tx".to_string(),
        ";   Number    Offset  |  Bus  [hex]  |  Reserved".to_string(),
        ";   |         [ms]    |  |    |      |  |  Data Length Code".to_string(),
        ";   |         |       |  |    |      |  |  |    Data [hex] ...".to_string(),
        ";   |         |       |  |    |      |  |  |    |".to_string(),
        ";---+-- ------+------ +- +- --+----- +- +- +--- +- -- -- -- -- -- -- --".to_string(),
    ];
    lines.iter().map(|l| format!("{l}\r\n")).collect()
}

/// A UTC wall-clock time split into its calendar fields.
struct Civil {
    unix_micros: i64,
    year: i64,
    month: u32,
    day: u32,
    weekday: u32,
    hour: u32,
    minute: u32,
    second: u32,
    micros: u32,
}

impl From<SystemTime> for Civil {
    fn from(time: SystemTime) -> Civil {
        let unix_micros = match time.duration_since(UNIX_EPOCH) {
            Ok(d) => i64::try_from(d.as_micros()).unwrap_or(i64::MAX),
            Err(e) => -i64::try_from(e.duration().as_micros()).unwrap_or(i64::MAX),
        };
        let days = unix_micros.div_euclid(86_400_000_000);
        let of_day = unix_micros.rem_euclid(86_400_000_000);
        // Howard Hinnant's days_from_civil inverse (public-domain algorithm "civil_from_days").
        let z = days + 719_468;
        let era = z.div_euclid(146_097);
        let doe = z.rem_euclid(146_097);
        let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
        let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
        let mp = (5 * doy + 2) / 153;
        let day = (doy - (153 * mp + 2) / 5 + 1) as u32;
        let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
        let year = yoe + era * 400 + i64::from(month <= 2);
        let secs = of_day / 1_000_000;
        Civil {
            unix_micros,
            year,
            month,
            day,
            // 1970-01-01 was a Thursday.
            weekday: (days + 4).rem_euclid(7) as u32,
            hour: (secs / 3600) as u32,
            minute: (secs / 60 % 60) as u32,
            second: (secs % 60) as u32,
            micros: (of_day % 1_000_000) as u32,
        }
    }
}

impl Civil {
    /// Days since 30 December 1899 (PEAK's `;$STARTTIME`, an OLE automation date).
    fn ole_days(&self) -> f64 {
        25_569.0 + self.unix_micros as f64 / 86_400_000_000.0
    }

    /// `18.12.2021 14:28:07.062.0` (PEAK's `Start time:`, the last digit tenths of a millisecond).
    fn peak_date(&self) -> String {
        format!(
            "{:02}.{:02}.{} {:02}:{:02}:{:02}.{:03}.{}",
            self.day,
            self.month,
            self.year,
            self.hour,
            self.minute,
            self.second,
            self.micros / 1000,
            self.micros / 100 % 10
        )
    }

    /// `Mon Jan 05 14:20:33.123 2026` (python-can's form of Vector's `date` line).
    fn asc_date(&self) -> String {
        const DAYS: [&str; 7] = ["Sun", "Mon", "Tue", "Wed", "Thu", "Fri", "Sat"];
        const MONTHS: [&str; 12] =
            ["Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec"];
        format!(
            "{} {} {:02} {:02}:{:02}:{:02}.{:03} {}",
            DAYS.get(self.weekday as usize).unwrap_or(&"Sun"),
            MONTHS.get(self.month.saturating_sub(1) as usize).unwrap_or(&"Jan"),
            self.day,
            self.hour,
            self.minute,
            self.second,
            self.micros / 1000,
            self.year
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Arc, Mutex};
    use std::time::Duration;

    /// A `Write` whose bytes the test can read afterwards.
    #[derive(Clone, Default)]
    struct Shared(Arc<Mutex<Vec<u8>>>);

    impl Write for Shared {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            self.0.lock().map_err(|_| io::Error::other("poisoned"))?.extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    fn written(format: TraceFormat) -> String {
        let shared = Shared::default();
        let start = UNIX_EPOCH + Duration::from_millis(1_767_622_833_123);
        let mut w = TraceWriter::with_start_time(Box::new(shared.clone()), format, start).unwrap();
        let f = CanFrame::from_raw(0x42B, &[0x00, 0xCB, 0x00]).unwrap();
        w.write(Instant::from_micros(5_001_124), "sim", Some(Direction::Tx), &f).unwrap();
        w.finish().unwrap();
        w.finish().unwrap();
        drop(w);
        let bytes = shared.0.lock().unwrap().clone();
        String::from_utf8(bytes).unwrap()
    }

    #[test]
    fn asc() {
        assert_eq!(
            written(TraceFormat::Asc),
            "date Mon Jan 05 14:20:33.123 2026\nbase hex  timestamps absolute\ninternal events logged\n\
             Begin Triggerblock Mon Jan 05 14:20:33.123 2026\n   0.000000 Start of measurement\n\
             \x20  5.001124 1  42B             Tx   d 3 00 CB 00\nEnd TriggerBlock\n"
        );
    }

    #[test]
    fn trc() {
        let text = written(TraceFormat::Trc);
        assert!(text.starts_with(";$FILEVERSION=2.1\r\n;$STARTTIME=46027.5976055903\r\n"), "{text}");
        assert!(text.contains(";   Start time: 05.01.2026 14:20:33.123.0\r\n"), "{text}");
        assert!(text.ends_with("      1      5001.124 DT  1     042B Tx -  3    00 CB 00\r\n"), "{text}");
    }

    #[test]
    fn csv_and_candump() {
        assert_eq!(
            written(TraceFormat::Csv),
            "timestamp,arbitration_id,extended,remote,error,dlc,data\n5.001124,0x42b,0,0,0,3,AMsA\n"
        );
        assert_eq!(written(TraceFormat::Candump), "(5.001124) sim 42B#00CB00\n");
    }

    #[rstest::rstest]
    #[case::asc("bench.asc", None, Ok(TraceFormat::Asc))]
    #[case::asc_upper("BENCH.ASC", None, Ok(TraceFormat::Asc))]
    #[case::trc("run.trc", None, Ok(TraceFormat::Trc))]
    #[case::csv("run.csv", None, Ok(TraceFormat::Csv))]
    #[case::log("bus.log", None, Ok(TraceFormat::Candump))]
    #[case::no_extension("bus", None, Ok(TraceFormat::Candump))]
    #[case::other_extension("bus.txt", None, Ok(TraceFormat::Candump))]
    #[case::given_wins("bench.asc", Some(TraceFormat::Candump), Ok(TraceFormat::Candump))]
    #[case::given_trc("bus.log", Some(TraceFormat::Trc), Ok(TraceFormat::Trc))]
    #[case::given_binary("x.log", Some(TraceFormat::Pcapng), Err("--format pcapng: --log writes"))]
    #[case::pcap_name(
        "x.pcap",
        None,
        Err("--log x.pcap: the extension names pcap, which --log does not write")
    )]
    #[case::blf_name("x.blf", None, Err("the extension names blf"))]
    fn the_log_format_follows_the_extension_unless_given(
        #[case] path: &str,
        #[case] given: Option<TraceFormat>,
        #[case] want: Result<TraceFormat, &str>,
    ) {
        match (log_format(Path::new(path), given), want) {
            (Ok(got), Ok(w)) => assert_eq!(got, w),
            (Err(e), Err(w)) => assert!(e.to_string().contains(w), "{e}"),
            (got, w) => panic!("{path} {given:?}: {got:?}, wanted {w:?}"),
        }
    }

    #[test]
    fn binary_formats_are_not_written() {
        for format in [TraceFormat::Pcap, TraceFormat::Pcapng, TraceFormat::Blf] {
            assert!(TraceWriter::new(Box::new(io::sink()), format).is_err());
        }
    }
}
