//! The bring-up of protocol §2 ([`Master::connect`]) and of the other I/O connections
//! ([`Master::connect_io`]), with its options and the summary of what was learned.

use super::*;

/// What `connect` learned.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct DeviceSummary {
    /// The device.
    pub mac: u8,
    /// `true` when the device answered UCMM (not group-2-only).
    pub ucmm_capable: bool,
    /// Identity attribute 1.
    pub vendor_id: Option<u16>,
    /// Identity attribute 2.
    pub device_type: Option<u16>,
    /// Identity attribute 3.
    pub product_code: Option<u16>,
    /// Connection 2 attribute 7.
    pub produced_size: Option<u16>,
    /// Connection 2 attribute 8.
    pub consumed_size: Option<u16>,
    /// The EPR the device applied.
    pub expected_packet_rate_ms: Option<u16>,
    /// The last poll response.
    pub last_input: Option<Vec<u8>>,
    /// The I/O connection other than poll (`--io strobe|cos|cyclic`): what it is and did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub io: Option<io::IoSummary>,
}

/// Options of `connect`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ConnectOptions {
    /// The device.
    pub target: MacId,
    /// Expected packet rate to set on the poll connection, ms (`--epr`).
    pub epr_ms: u16,
    /// Poll cycles after the connection is established (`--polls`).
    pub polls: u32,
    /// Poll output data (`--output`); `None`: the consumed size in zero bytes.
    pub output: Option<Vec<u8>>,
    /// Read the connections' states back after the polls and check the 4 × EPR watchdog
    /// (`--verify-state`; adds frames after the bring-up).
    pub verify_state: bool,
}

impl Default for ConnectOptions {
    fn default() -> Self {
        ConnectOptions {
            target: MacId::from_low_bits(5),
            epr_ms: 100,
            polls: 1,
            output: None,
            verify_state: false,
        }
    }
}

impl Master<'_, '_> {
    /// The whole bring-up of protocol §2 against `opts.target`. Every frame is recorded in the
    /// session with its verdict; the result summarises what was learned.
    pub fn connect(&mut self, opts: &ConnectOptions) -> Result<DeviceSummary, MasterError> {
        self.connect_io(opts, &io::IoOptions::default())
    }

    /// The bring-up with the I/O connection of `io` ([`io::IoKind`]): for poll exactly
    /// [`Master::connect`]'s; for strobe, COS and cyclic the same up to the Identity reads, then
    /// that connection allocated through the explicit connection, configured and exchanged on
    /// for `opts.polls` cycles ([`Master::establish_io`], [`Master::strobe`],
    /// [`Master::await_production`], [`Master::send_output`]); the connection stays with the
    /// master for more cycles ([`Master::io_connection`]).
    pub fn connect_io(
        &mut self,
        opts: &ConnectOptions,
        io: &io::IoOptions,
    ) -> Result<DeviceSummary, MasterError> {
        io.validate()?;
        let target = opts.target;
        if target == self.config.mac {
            return Err(UsageError::OwnMac(target).into());
        }
        self.set_device(target);
        let mut summary = DeviceSummary { mac: target.as_raw(), ..DeviceSummary::default() };
        self.network_access()?;
        self.await_online(&[target])?;
        summary.ucmm_capable = self.ucmm_probe(target)?;
        self.allocate(target, Port::Group2Only, AllocationChoice::EXPLICIT)?;
        // Explicit connection: watchdog timeout action = deferred delete (protocol §5.4).
        let (data, i) = self.set(target, class::CONNECTION, 1, 12, &[3])?;
        let failures = if data.is_empty() {
            Vec::new()
        } else {
            vec![format!("set response carries data {}", hex(&data))]
        };
        self.judge(i, "explicit watchdog action = deferred delete", failures);
        summary.vendor_id = self.get_u16(target, class::IDENTITY, 1, 1)?;
        if let (Some(v), Some(dup)) = (summary.vendor_id, self.tracker.announced(target.as_raw())) {
            if v != dup.vendor_id {
                let last = self.last_record;
                self.judge(
                    last,
                    "",
                    vec![format!(
                        "vendor ID 0x{v:04X} differs from the duplicate MAC ID check's 0x{:04X}",
                        dup.vendor_id
                    )],
                );
            }
        }
        summary.device_type = self.get_u16(target, class::IDENTITY, 1, 2)?;
        summary.product_code = self.get_u16(target, class::IDENTITY, 1, 3)?;
        if io.kind != io::IoKind::Poll {
            self.exchange_io(opts, io, &mut summary)?;
            return Ok(summary);
        }
        self.allocate(target, Port::Explicit, AllocationChoice::POLL)?;
        summary.produced_size = self.get_u16(target, class::CONNECTION, 2, 7)?;
        summary.consumed_size = self.get_u16(target, class::CONNECTION, 2, 8)?;
        let produced = summary.produced_size.unwrap_or(0);
        let consumed = summary.consumed_size.unwrap_or(0);
        let (data, i) = self.set(target, class::CONNECTION, 2, 9, &opts.epr_ms.to_le_bytes())?;
        let applied = match data.as_slice() {
            [a, b] => {
                let applied = u16::from_le_bytes([*a, *b]);
                let failures = if applied >= opts.epr_ms {
                    Vec::new()
                } else {
                    vec![format!(
                        "EPR applied {applied} ms is below the {} ms requested (must round up)",
                        opts.epr_ms
                    )]
                };
                self.judge(
                    i,
                    &format!(
                        "EPR {applied} ms applied; poll established, watchdog 4 x EPR = {} ms",
                        u32::from(applied) * 4
                    ),
                    failures,
                );
                applied
            }
            [] => {
                self.judge(i, "EPR set (no applied value returned)", Vec::new());
                opts.epr_ms
            }
            other => {
                self.judge(i, "", vec![format!("EPR response data {}, expected 2 bytes", hex(other))]);
                opts.epr_ms
            }
        };
        summary.expected_packet_rate_ms = Some(applied);
        let output = match &opts.output {
            Some(o) if o.len() > usize::from(consumed) => {
                return Err(UsageError::OutputTooLong { given: o.len(), consumed, attribute: false }.into())
            }
            Some(o) => o.clone(),
            None => vec![0; usize::from(consumed)],
        };
        let epr = Duration::from_millis(u64::from(applied.max(1)));
        let timeout = if epr > MIN_POLL_TIMEOUT { epr } else { MIN_POLL_TIMEOUT };
        let mut next_poll = self.session.now();
        let mut last_poll = next_poll;
        for _ in 0..opts.polls {
            self.idle_until(next_poll)?;
            last_poll = self.session.now();
            let input = self.poll(target, &output, produced, consumed, timeout)?;
            summary.last_input = Some(input);
            next_poll = last_poll + epr;
        }
        if opts.verify_state {
            self.verify_state(target, applied, last_poll, opts.polls > 0)?;
        }
        Ok(summary)
    }

    /// The strobe, COS or cyclic part of [`Master::connect_io`]: established, then
    /// `opts.polls` cycles at the EPR.
    fn exchange_io(
        &mut self,
        opts: &ConnectOptions,
        io: &io::IoOptions,
        summary: &mut DeviceSummary,
    ) -> Result<(), MasterError> {
        let target = opts.target;
        self.establish_io(target, opts.epr_ms, io)?;
        let conn = self.io_connection().cloned().ok_or(UsageError::NoIoConnection)?;
        summary.produced_size = Some(conn.produced);
        summary.consumed_size = Some(conn.consumed);
        summary.expected_packet_rate_ms = Some(conn.epr_ms);
        let output = match &opts.output {
            Some(_) if io.kind == io::IoKind::Strobe => return Err(UsageError::StrobeOutput.into()),
            Some(o) if o.len() > usize::from(conn.consumed) => {
                return Err(UsageError::OutputTooLong {
                    given: o.len(),
                    consumed: conn.consumed,
                    attribute: true,
                }
                .into())
            }
            Some(o) => o.clone(),
            None => vec![0; usize::from(conn.consumed)],
        };
        let epr = Duration::from_millis(u64::from(conn.epr_ms.max(1)));
        let mut next = self.session.now();
        for _ in 0..opts.polls {
            let input = match io.kind {
                io::IoKind::Strobe => {
                    self.idle_until(next)?;
                    next = self.session.now() + epr;
                    self.strobe()?
                }
                _ => {
                    let input = self.await_production()?;
                    if conn.consumed > 0 {
                        self.send_output(&output)?;
                    }
                    input
                }
            };
            summary.last_input = Some(input);
        }
        if opts.verify_state {
            let inst = io.kind.instance();
            let (data, i) = self.get(target, class::CONNECTION, inst, 1)?;
            let failures = if data.as_slice() == [3] {
                Vec::new()
            } else {
                vec![format!("Connection {inst} state {}, expected 3 (established)", hex(&data))]
            };
            self.judge(i, &format!("{} connection established", io.kind), failures);
        }
        summary.io = self.io_connection().map(|c| c.summary.clone());
        Ok(())
    }

    /// Reads the connection states back and checks the poll watchdog fires at 4 × EPR
    /// (`--verify-state`).
    fn verify_state(
        &mut self,
        target: MacId,
        epr_ms: u16,
        last_poll: Instant,
        polled: bool,
    ) -> Result<(), MasterError> {
        let expect = |m: &mut Self, inst: u16, attr: u8, want: u8, what: &str| -> Result<(), MasterError> {
            let (data, i) = m.get(target, class::CONNECTION, inst, attr)?;
            let failures = if data.as_slice() == [want] {
                Vec::new()
            } else {
                vec![format!("{what}: read {}, expected {want}", hex(&data))]
            };
            m.judge(i, what, failures);
            Ok(())
        };
        expect(self, 1, 1, 3, "explicit connection established")?;
        expect(self, 1, 12, 3, "explicit watchdog action deferred delete")?;
        expect(self, 2, 1, 3, "poll connection established")?;
        if polled {
            let watchdog = Duration::from_millis(4 * u64::from(epr_ms));
            let margin = Duration::from_millis(u64::from(epr_ms / 2).max(5));
            let before = last_poll
                + Duration::from_micros(watchdog.total_micros().saturating_sub(margin.total_micros()));
            self.idle_until(before)?;
            expect(self, 2, 1, 3, "poll still established just before 4 x EPR")?;
            self.idle_until(last_poll + watchdog + margin)?;
            expect(self, 2, 1, 4, "poll timed out just after 4 x EPR")?;
        }
        Ok(())
    }
}
