use super::*;
use crate::serial::framed_profile::MAX_COMMAND_FORMATS;
use crate::serial::modbus::schedule::MAX_PERIOD_MS;
use crate::serial::modbus::SCAN_LIST_CAPACITY;
use crate::serial::IDLE_FRAME_CAPACITY;
use proptest::prelude::*;
use rstest::rstest;
use std::string::ToString;
use std::vec::Vec;

/// The Modbus gateway of `descriptions/modbus-meter.toml`.
pub(crate) fn modbus_meter() -> ConverterConfig {
    let scan = heapless::Vec::from_iter([
        ScanEntry {
            unit: 1,
            function: Function::ReadInputRegisters,
            address: 0,
            count: 4,
            offset: 0,
            word_order: Default::default(),
            period_ms: None,
            write: Default::default(),
            trigger_offset: None,
        },
        ScanEntry {
            unit: 1,
            function: Function::ReadHoldingRegisters,
            address: 100,
            count: 2,
            offset: 8,
            word_order: Default::default(),
            period_ms: None,
            write: Default::default(),
            trigger_offset: None,
        },
        ScanEntry {
            unit: 1,
            function: Function::WriteMultipleRegisters,
            address: 16,
            count: 2,
            offset: 0,
            word_order: Default::default(),
            period_ms: None,
            write: Default::default(),
            trigger_offset: None,
        },
    ]);
    let mut m = ModbusConfig::new(scan);
    m.response_timeout_ms = 200;
    m.retries = 1;
    m.health = HealthConfig { stale_timeout_ms: 1000, stale_policy: StalePolicy::Clear };
    m.on_fault = IdleAction::send(&[0x01, 0x06, 0x00, 0x10, 0x00, 0x00]).unwrap();
    let mut c = ConverterConfig {
        profile: ProfileConfig::Modbus(m),
        input: InputAssembly::WithStatus,
        ..ConverterConfig::breaker_reference()
    };
    c.device = c.device_config();
    c
}

fn breaker() -> ConverterConfig {
    let mut c = ConverterConfig::breaker_reference();
    c.device = c.device_config();
    c
}

fn image(config: &ConverterConfig) -> Vec<u8> {
    let mut out = [0u8; MAX_IMAGE];
    let n = encode(config, &mut out).unwrap();
    out[..n].to_vec()
}

/// Re-seals a modified image: fixes the body length and the CRC.
fn resealed(mut bytes: Vec<u8>) -> Vec<u8> {
    bytes.truncate(bytes.len() - CRC_LEN);
    let body = u16::try_from(bytes.len() - HEADER_LEN).unwrap();
    bytes[5..7].copy_from_slice(&body.to_le_bytes());
    let crc = crc32(&bytes);
    bytes.extend_from_slice(&crc.to_le_bytes());
    bytes
}

/// The largest configuration: every list full, the longest strings.
fn largest() -> ConverterConfig {
    let mut c = modbus_meter();
    c.device.identity.product_name.clear();
    c.device.identity.product_name.push_str(&"N".repeat(32)).unwrap();
    if let ProfileConfig::Modbus(m) = &mut c.profile {
        m.scan.clear();
        m.input_len = SCAN_LIST_CAPACITY as u16;
        for i in 0..SCAN_LIST_CAPACITY as u16 {
            let e = ScanEntry {
                unit: 1,
                function: Function::ReadCoils,
                address: i,
                count: 8,
                offset: i,
                word_order: Default::default(),
                period_ms: Some(MAX_PERIOD_MS),
                write: Default::default(),
                trigger_offset: None,
            };
            m.scan.push(e).unwrap();
        }
        m.on_idle = IdleAction::send(&[1; IDLE_FRAME_CAPACITY]).unwrap();
        m.on_fault = IdleAction::send(&[1; IDLE_FRAME_CAPACITY]).unwrap();
    }
    c.device = c.device_config();
    c
}

#[test]
fn the_breaker_reference_image_is_the_encoding_of_the_reference() {
    let encoded = image(&ConverterConfig::breaker_reference());
    assert_eq!(BREAKER_REFERENCE.as_slice(), encoded, "update BREAKER_REFERENCE to {encoded:?}");
    assert_eq!(decode(&BREAKER_REFERENCE).unwrap(), breaker());
}

#[test]
fn the_layout_points_at_the_parameter_values() {
    let (_, l) = decode_with_layout(&BREAKER_REFERENCE).unwrap();
    let at = |o: u16, n: usize| &BREAKER_REFERENCE[usize::from(o)..usize::from(o) + n];
    assert_eq!(at(l.serial, 5), [0x80, 0x25, 0, 0, 0], "9600 baud, 8N1");
    assert_eq!(at(l.input, 1), [0]);
    assert_eq!(at(l.timing, 5), [0xF4, 0x01, 0, 0, 2], "500 ms, 2 retries");
    assert_eq!(at(l.health, 5), [0xB8, 0x0B, 0, 0, 0], "3000 ms, hold");
    let meter = image(&modbus_meter());
    let (config, l) = decode_with_layout(&meter).unwrap();
    let ProfileConfig::Modbus(m) = config.profile else { panic!("a Modbus gateway") };
    let u32_at = |o: u16| u32::from_le_bytes(meter[usize::from(o)..usize::from(o) + 4].try_into().unwrap());
    assert_eq!(u32_at(l.serial), m.serial.baud);
    assert_eq!(meter[usize::from(l.input)], 1, "with status");
    assert_eq!(u32_at(l.timing), m.response_timeout_ms);
    assert_eq!(meter[usize::from(l.timing) + 4], m.retries);
    assert_eq!(u32_at(l.timing + 5), m.poll_period_ms);
    assert_eq!(u32_at(l.health), m.health.stale_timeout_ms);
    assert_eq!(meter[usize::from(l.health) + 4], 1, "clear");
}

#[test]
fn reseal_writes_the_crc_of_the_changed_bytes() {
    let mut bytes = BREAKER_REFERENCE;
    bytes[usize::from(decode_with_layout(&bytes).unwrap().1.timing) + 4] = 3;
    assert!(matches!(decode(&bytes), Err(ImageError::CrcMismatch { .. })));
    reseal(&mut bytes);
    let ProfileConfig::Framed(f) = decode(&bytes).unwrap().profile else { panic!("framed") };
    assert_eq!(f.sequencer.retries, 3);
    reseal(&mut [0u8; 3]);
}

#[test]
fn crc_is_the_zlib_crc32() {
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
}

#[rstest]
#[case::breaker(breaker())]
#[case::modbus(modbus_meter())]
#[case::largest(largest())]
fn round_trip(#[case] config: ConverterConfig) {
    let bytes = image(&config);
    assert_eq!(&bytes[..5], b"DNCI\x01");
    assert_eq!(decode(&bytes), Ok(config));
}

#[test]
fn largest_configuration_fits_max_image() {
    let n = image(&largest()).len();
    assert_eq!(n, 365);
    assert!(n <= MAX_IMAGE);
}

#[test]
fn encode_refuses_a_short_buffer() {
    let n = image(&breaker()).len();
    let mut out = std::vec![0u8; n - 1];
    assert_eq!(encode(&breaker(), &mut out), Err(ImageError::BufferTooSmall));
    let mut out = std::vec![0u8; n];
    assert_eq!(encode(&breaker(), &mut out), Ok(n));
}

#[rstest]
#[case::empty(|_: &mut Vec<u8>| -> Vec<u8> { Vec::new() }, ImageError::Truncated(0))]
#[case::truncated(|b: &mut Vec<u8>| b[..10].to_vec(), ImageError::Truncated(10))]
#[case::oversized(|b: &mut Vec<u8>| { let mut v = b.clone(); v.resize(MAX_IMAGE + 1, 0); v }, ImageError::TooLarge(MAX_IMAGE + 1))]
#[case::bad_magic(|b: &mut Vec<u8>| { b[0] = b'X'; b.clone() }, ImageError::BadMagic)]
#[case::wrong_version(|b: &mut Vec<u8>| { b[4] = 2; b.clone() }, ImageError::UnsupportedVersion(2))]
#[case::length_mismatch(|b: &mut Vec<u8>| { b.pop(); b.clone() }, ImageError::LengthMismatch { stated: 87, actual: 86 })]
fn refusals(#[case] damage: fn(&mut Vec<u8>) -> Vec<u8>, #[case] expected: ImageError) {
    let mut bytes = image(&breaker());
    assert_eq!(bytes.len(), 98, "the breaker's image");
    assert_eq!(decode(&damage(&mut bytes)), Err(expected));
}

#[test]
fn wrong_crc() {
    let mut bytes = image(&breaker());
    bytes[20] ^= 1;
    assert!(matches!(decode(&bytes), Err(ImageError::CrcMismatch { .. })));
}

#[test]
fn malformed_body() {
    // The profile kind byte (after 12 + 1 + 23 identity bytes, 6 network bytes, 1 io byte).
    let mut bytes = image(&breaker());
    bytes[HEADER_LEN + 43] = 7;
    assert_eq!(decode(&resealed(bytes)), Err(ImageError::Malformed { offset: 43 }));
    // A byte left over.
    let mut bytes = image(&breaker());
    bytes.insert(bytes.len() - CRC_LEN, 0);
    assert_eq!(decode(&resealed(bytes)), Err(ImageError::Malformed { offset: 87 }));
}

/// The image offset of scan entry `i`'s function byte in `modbus_meter()`'s image.
fn function_byte(bytes: &[u8], i: usize) -> usize {
    let c = modbus_meter();
    let ProfileConfig::Modbus(m) = &c.profile else { unreachable!() };
    // The scan count byte, then 8 bytes per entry (the function second), then health and actions.
    let scan_count = bytes.len() - CRC_LEN - health_and_actions_len(m) - 8 * m.scan.len() - 1;
    scan_count + 1 + 8 * i + 1
}

fn health_and_actions_len(m: &ModbusConfig) -> usize {
    let action = |a: &IdleAction| a.frame().map_or(1, |f| 2 + f.len());
    5 + action(&m.on_idle) + action(&m.on_fault)
}

#[rstest]
#[case::registers(WordOrder::Registers, 0x04)]
#[case::abcd(WordOrder::Abcd, 0x24)]
#[case::badc(WordOrder::Badc, 0x44)]
#[case::cdab(WordOrder::Cdab, 0x64)]
#[case::dcba(WordOrder::Dcba, 0x84)]
fn the_word_order_rides_in_bits_5_to_7_of_the_function_byte(#[case] order: WordOrder, #[case] byte: u8) {
    let mut c = modbus_meter();
    if let ProfileConfig::Modbus(m) = &mut c.profile {
        m.scan[0].word_order = order;
    }
    let bytes = image(&c);
    assert_eq!(bytes[function_byte(&bytes, 0)], byte);
    assert_eq!(decode(&bytes), Ok(c));
}

#[test]
fn an_image_without_word_orders_reads_as_before() {
    // The image of a version-1 configuration written before word orders existed: every function
    // byte is a plain Modbus code (4, 3, 16), and every entry reads as `WordOrder::Registers`.
    let bytes = image(&modbus_meter());
    let at = function_byte(&bytes, 0);
    assert_eq!([bytes[at], bytes[at + 8], bytes[at + 16]], [4, 3, 16]);
    let ProfileConfig::Modbus(m) = decode(&bytes).unwrap().profile else { panic!("not Modbus") };
    assert!(m.scan.iter().all(|e| e.word_order == WordOrder::Registers));
}

#[test]
fn an_unknown_word_order_or_a_pair_order_on_an_odd_count_is_refused() {
    let bytes = image(&modbus_meter());
    let at = function_byte(&bytes, 0);
    let mut unknown = bytes.clone();
    unknown[at] = 5 << 5 | 4;
    let offset = u16::try_from(at - HEADER_LEN).unwrap();
    assert_eq!(decode(&resealed(unknown)), Err(ImageError::Malformed { offset }));
    // Entry 0 reads 4 registers: CDAB is fine; on entry 1 with an odd count it is not.
    let mut c = modbus_meter();
    if let ProfileConfig::Modbus(m) = &mut c.profile {
        m.scan[1].count = 1;
        m.scan[1].word_order = WordOrder::Cdab;
    }
    let e = decode(&image(&c)).unwrap_err();
    assert_eq!(
        e.to_string(),
        "profile.modbus.scan[1].word_order: a 32-bit word order needs function 3, 4 or 16 and an even register count"
    );
}

/// The modbus-meter gateway with a periodic read (entry 1), a triggered write (entry 2, trigger
/// byte 4) and the output image grown to hold the trigger byte.
fn scheduled_meter() -> ConverterConfig {
    let mut c = modbus_meter();
    if let ProfileConfig::Modbus(m) = &mut c.profile {
        m.scan[1].period_ms = Some(0x0001_86A0);
        m.scan[2].write = WriteMode::Trigger;
        m.scan[2].trigger_offset = Some(4);
        m.output_len = 5;
    }
    c.device = c.device_config();
    c
}

#[test]
fn a_schedule_follows_its_entry_flagged_in_bit_15_of_the_offset() {
    let c = scheduled_meter();
    let bytes = image(&c);
    let plain = image(&modbus_meter());
    // Entry 1 gains flags 0x01 and the period 100 000 ms; entry 2 flags 0x0A (trigger, mode 2)
    // and the trigger byte 4; the output length grows from 4 to 5.
    assert_eq!(bytes.len(), plain.len() + 5 + 3);
    let entry1 = [0x01, 0x03, 100, 0, 2, 0, 8, 0x80, 0x01, 0xA0, 0x86, 0x01, 0x00];
    let entry2 = [0x01, 0x10, 16, 0, 2, 0, 0, 0x80, 0x0A, 4, 0];
    let at = bytes.windows(entry1.len()).position(|w| w == entry1).expect("entry 1 with its period");
    assert_eq!(bytes[at + entry1.len()..at + entry1.len() + entry2.len()], entry2);
    assert_eq!(decode(&bytes), Ok(c));
}

#[test]
fn an_image_without_schedules_reads_as_before() {
    let ProfileConfig::Modbus(m) = decode(&image(&modbus_meter())).unwrap().profile else {
        panic!("not Modbus")
    };
    assert!(m
        .scan
        .iter()
        .all(|e| e.period_ms.is_none() && e.write == WriteMode::Change && e.trigger_offset.is_none()));
}

#[test]
fn an_unknown_write_mode_or_an_invalid_schedule_is_refused() {
    let bytes = image(&scheduled_meter());
    let flags = bytes.windows(3).position(|w| w == [0x80, 0x0A, 4]).unwrap() + 1;
    let mut unknown = bytes.clone();
    unknown[flags] = 0x0E;
    let offset = u16::try_from(flags - HEADER_LEN).unwrap();
    assert_eq!(decode(&resealed(unknown)), Err(ImageError::Malformed { offset }));
    // Mode "change" with a trigger byte: decoded, then refused with the description's words.
    let mut change = bytes.clone();
    change[flags] = 0x02;
    assert_eq!(
        decode(&resealed(change)).unwrap_err().to_string(),
        "profile.modbus.scan[2].trigger_offset: a write entry takes trigger_offset with write = \"trigger\" only"
    );
}

#[test]
fn invalid_values_name_their_key_as_the_description_loader_does() {
    let mut bytes = image(&breaker());
    // The MAC ID follows the 36 identity bytes.
    bytes[HEADER_LEN + 36] = 70;
    let e = decode(&resealed(bytes)).unwrap_err();
    assert_eq!(e, ImageError::Invalid(InvalidConfig::MacId(70)));
    assert_eq!(e.to_string(), "network.mac_id: 70 is outside 0..=63");

    let mut c = modbus_meter();
    if let ProfileConfig::Modbus(m) = &mut c.profile {
        m.scan[1].offset = 30;
    }
    let e = decode(&image(&c)).unwrap_err();
    assert_eq!(e.to_string(), "profile.modbus.scan[1].offset: 30 is outside the allowed range 0..=8");
}

fn serial() -> impl Strategy<Value = SerialSettings> {
    (prop_oneof![Just(9600u32), 0..5_000_000u32], any::<bool>(), 0..3u8, any::<bool>()).prop_map(
        |(baud, seven, parity, two)| SerialSettings {
            baud,
            data_bits: if seven { DataBits::Seven } else { DataBits::Eight },
            parity: [Parity::None, Parity::Even, Parity::Odd][usize::from(parity)],
            stop_bits: if two { StopBits::Two } else { StopBits::One },
        },
    )
}

fn health() -> impl Strategy<Value = HealthConfig> {
    (0..4_000_000u32, any::<bool>()).prop_map(|(stale_timeout_ms, clear)| HealthConfig {
        stale_timeout_ms,
        stale_policy: if clear { StalePolicy::Clear } else { StalePolicy::HoldLastValue },
    })
}

fn action() -> impl Strategy<Value = IdleAction> {
    proptest::option::of(proptest::collection::vec(any::<u8>(), 0..=IDLE_FRAME_CAPACITY))
        .prop_map(|f| f.map_or(IdleAction::Nothing, |f| IdleAction::send(&f).unwrap()))
}

fn framed() -> impl Strategy<Value = ProfileConfig> {
    let framing = (any::<u8>(), 0..3u8, 0..20u8, proptest::option::of(any::<u8>()), 0..4u8, 0..=255u8)
        .prop_map(|(start, kind, n, end, ck, max_len)| FramedConfig {
            start,
            length: [LengthField::Byte, LengthField::Fixed(n), LengthField::Delimited][usize::from(kind)],
            end,
            checksum: [Checksum::None, Checksum::Sum8, Checksum::Xor8, Checksum::Crc16Modbus]
                [usize::from(ck)],
            max_len,
        });
    let ack = proptest::option::of((0..10u8, any::<u8>(), any::<u8>()))
        .prop_map(|a| a.map(|(data_len, flag, ok_status)| AckFormat { data_len, flag, ok_status }));
    let commands = proptest::collection::vec((any::<u8>(), any::<u8>(), 0..8u8), 0..=MAX_COMMAND_FORMATS);
    let sequencer = (0..70_000u32, 0..12u8, any::<bool>(), action(), action()).prop_map(
        |(response_timeout_ms, retries, execute_first, on_idle, on_fault)| SequencerConfig {
            response_timeout_ms,
            retries,
            execute_first,
            on_idle,
            on_fault,
        },
    );
    (serial(), framing, 0..70u8, ack, commands, sequencer, health()).prop_map(
        |(serial, framing, status_len, ack, commands, sequencer, health)| {
            ProfileConfig::Framed(FramedProfileConfig {
                serial,
                framing,
                status_len,
                ack,
                commands: commands
                    .into_iter()
                    .map(|(code, wire, args)| CommandFormat { code, wire, args })
                    .collect(),
                sequencer,
                health,
            })
        },
    )
}

fn modbus() -> impl Strategy<Value = ProfileConfig> {
    const FUNCTIONS: [u8; 8] = [1, 2, 3, 4, 5, 6, 15, 16];
    let schedule = (proptest::option::of(0..4_000_000u32), 0..3usize, proptest::option::of(0..70u16));
    let entry = (1..250u8, 0..8usize, any::<u16>(), 0..130u16, 0..70u16, 0..WordOrder::ALL.len(), schedule)
        .prop_map(|(unit, f, address, count, offset, w, (period_ms, mode, trigger_offset))| ScanEntry {
            unit,
            function: Function::from_code(FUNCTIONS[f]).unwrap(),
            address,
            count,
            offset,
            word_order: WordOrder::ALL[w],
            period_ms,
            write: WriteMode::ALL[mode],
            trigger_offset,
        });
    let scan = proptest::collection::vec(entry, 0..=SCAN_LIST_CAPACITY);
    (
        serial(),
        0..70_000u32,
        0..12u8,
        0..4_000_000u32,
        0..70u16,
        0..70u16,
        (any::<bool>(), 0..3u8),
        scan,
        health(),
        action(),
        action(),
    )
        .prop_map(
            |(
                serial,
                rt,
                retries,
                poll,
                input_len,
                output_len,
                (big, framing),
                scan,
                health,
                on_idle,
                on_fault,
            )| {
                ProfileConfig::Modbus(ModbusConfig {
                    serial,
                    framing: [Framing::Rtu, Framing::Ascii, Framing::Tcp][usize::from(framing)],
                    response_timeout_ms: rt,
                    retries,
                    poll_period_ms: poll,
                    input_len,
                    output_len,
                    byte_order: if big { ByteOrder::BigEndian } else { ByteOrder::LittleEndian },
                    scan: scan.into_iter().collect(),
                    health,
                    on_idle,
                    on_fault,
                    valid_bits_offset: None,
                })
            },
        )
}

fn config() -> impl Strategy<Value = ConverterConfig> {
    let identity =
        (any::<u16>(), any::<u16>(), any::<u16>(), 0..130u8, any::<u8>(), any::<u32>(), "[ -~]{0,32}|.{0,8}");
    let network = (0..64u8, 0..3u8, 0..130u8, any::<bool>(), any::<bool>(), 0..3u16);
    (identity, network, any::<bool>(), prop_oneof![framed(), modbus()]).prop_map(
        |((vendor_id, device_type, product_code, major, minor, serial, name), net, status, profile)| {
            let (mac, baud, port, bus_off_interrupt, programmable, epr) = net;
            let mut product_name = heapless::String::new();
            let _ = product_name.push_str(&name);
            let mut c = ConverterConfig {
                device: DeviceConfig {
                    identity: Identity {
                        vendor_id,
                        device_type,
                        product_code,
                        major_revision: major,
                        minor_revision: minor,
                        serial_number: serial,
                        product_name,
                    },
                    mac_id: MacId::new(mac).unwrap(),
                    baud_rate: BaudRate::from_attribute_value(baud).unwrap(),
                    port,
                    bus_off_interrupt,
                    switches: Switches { programmable, ..Switches::default() },
                    epr_resolution_ms: epr,
                    ..DeviceConfig::reference()
                },
                profile,
                input: if status { InputAssembly::WithStatus } else { InputAssembly::Plain },
            };
            c.device = c.device_config();
            c
        },
    )
}

proptest! {
    /// Every configuration comes back as it was when it is valid, and is refused with the
    /// same error as `check` when it is not.
    #[test]
    fn decode_inverts_encode_and_checks_like_check(c in config()) {
        let bytes = image(&c);
        prop_assert!(bytes.len() <= MAX_IMAGE);
        let expected = c.check().map(|()| c.clone()).map_err(ImageError::Invalid);
        prop_assert_eq!(decode(&bytes), expected);
    }

    #[test]
    fn decode_accepts_any_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let _ = decode(&bytes);
    }

    /// Any change to a valid image, resealed or not, is refused or decodes to a valid
    /// configuration; it never panics.
    #[test]
    fn damaged_images_never_panic(at in 0..200usize, xor in 1..=255u8, seal in any::<bool>()) {
        let mut bytes = image(&modbus_meter());
        let at = at % bytes.len();
        bytes[at] ^= xor;
        let bytes = if seal && at >= HEADER_LEN && at < bytes.len() - CRC_LEN { resealed(bytes) } else { bytes };
        if let Ok(c) = decode(&bytes) {
            prop_assert_eq!(c.check(), Ok(()));
        }
    }
}
