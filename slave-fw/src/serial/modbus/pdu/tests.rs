use super::*;
use proptest::prelude::*;
use rstest::rstest;

/// `hex` without its CRC, with the CRC appended.
fn adu(body: &[u8]) -> std::vec::Vec<u8> {
    let mut v = body.to_vec();
    v.extend_from_slice(&crc16_modbus(body).to_le_bytes());
    v
}

// Requests of every function, both ways. Examples from the Modbus Application Protocol
// specification §6 on unit 0x11 where it gives them.
#[rstest]
#[case::read_coils(Request::ReadCoils { address: 0x0013, count: 0x0013 }, &[0x11, 0x01, 0x00, 0x13, 0x00, 0x13])]
#[case::read_discrete(Request::ReadDiscreteInputs { address: 0x00C4, count: 0x0016 }, &[0x11, 0x02, 0x00, 0xC4, 0x00, 0x16])]
#[case::read_holding(Request::ReadHoldingRegisters { address: 0x006B, count: 3 }, &[0x11, 0x03, 0x00, 0x6B, 0x00, 0x03])]
#[case::read_input(Request::ReadInputRegisters { address: 0x0008, count: 1 }, &[0x11, 0x04, 0x00, 0x08, 0x00, 0x01])]
#[case::write_coil_on(Request::WriteSingleCoil { address: 0x00AC, value: true }, &[0x11, 0x05, 0x00, 0xAC, 0xFF, 0x00])]
#[case::write_coil_off(Request::WriteSingleCoil { address: 0x00AC, value: false }, &[0x11, 0x05, 0x00, 0xAC, 0x00, 0x00])]
#[case::write_register(Request::WriteSingleRegister { address: 0x0001, value: 0x0003 }, &[0x11, 0x06, 0x00, 0x01, 0x00, 0x03])]
#[case::write_coils(Request::WriteMultipleCoils { address: 0x0013, count: 10, bits: &[0xCD, 0x01] }, &[0x11, 0x0F, 0x00, 0x13, 0x00, 0x0A, 0x02, 0xCD, 0x01])]
#[case::write_registers(Request::WriteMultipleRegisters { address: 0x0001, values: &[0x00, 0x0A, 0x01, 0x02] }, &[0x11, 0x10, 0x00, 0x01, 0x00, 0x02, 0x04, 0x00, 0x0A, 0x01, 0x02])]
fn request_codec(#[case] request: Request<'static>, #[case] body: &[u8]) {
    let wire = adu(body);
    let mut out = [0u8; ADU_CAPACITY];
    let n = request.emit(0x11, &mut out).unwrap();
    assert_eq!(&out[..n], wire.as_slice());
    assert_eq!(request.buffer_len(), wire.len());
    assert_eq!(Request::parse(&wire), Ok((0x11, request)));
    assert_eq!(request_len(&wire[..7]), Ok(Some(wire.len())));
}

#[test]
fn read_holding_request_matches_published_crc() {
    let mut out = [0u8; 8];
    Request::ReadHoldingRegisters { address: 0, count: 10 }.emit(1, &mut out).unwrap();
    assert_eq!(out, [0x01, 0x03, 0x00, 0x00, 0x00, 0x0A, 0xC5, 0xCD]);
}

#[rstest]
#[case::read_coils(Response::ReadCoils(&[0xCD, 0x6B, 0x05]), &[0x11, 0x01, 0x03, 0xCD, 0x6B, 0x05])]
#[case::read_discrete(Response::ReadDiscreteInputs(&[0xAC, 0xDB, 0x35]), &[0x11, 0x02, 0x03, 0xAC, 0xDB, 0x35])]
#[case::read_holding(Response::ReadHoldingRegisters(&[0x02, 0x2B, 0x00, 0x00, 0x00, 0x64]), &[0x11, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64])]
#[case::read_input(Response::ReadInputRegisters(&[0x00, 0x0A]), &[0x11, 0x04, 0x02, 0x00, 0x0A])]
#[case::write_coil(Response::WriteSingleCoil { address: 0x00AC, value: true }, &[0x11, 0x05, 0x00, 0xAC, 0xFF, 0x00])]
#[case::write_register(Response::WriteSingleRegister { address: 0x0001, value: 0x0003 }, &[0x11, 0x06, 0x00, 0x01, 0x00, 0x03])]
#[case::write_coils(Response::WriteMultipleCoils { address: 0x0013, count: 10 }, &[0x11, 0x0F, 0x00, 0x13, 0x00, 0x0A])]
#[case::write_registers(Response::WriteMultipleRegisters { address: 0x0001, count: 2 }, &[0x11, 0x10, 0x00, 0x01, 0x00, 0x02])]
#[case::exception(Response::Exception { function: 0x03, code: ExceptionCode::IllegalDataAddress }, &[0x11, 0x83, 0x02])]
#[case::exception_unknown(Response::Exception { function: 0x10, code: ExceptionCode::Unknown(0x42) }, &[0x11, 0x90, 0x42])]
fn response_codec(#[case] response: Response<'static>, #[case] body: &[u8]) {
    let wire = adu(body);
    let mut out = [0u8; ADU_CAPACITY];
    let n = response.emit(0x11, &mut out).unwrap();
    assert_eq!(&out[..n], wire.as_slice());
    assert_eq!(response.buffer_len(), wire.len());
    assert_eq!(Response::parse(&wire), Ok((0x11, response)));
    assert_eq!(response_len(&wire[..3]), Ok(Some(wire.len())));
}

#[test]
fn read_input_response_matches_published_crc() {
    let wire = [0x01, 0x04, 0x02, 0xFF, 0xFF, 0xB8, 0x80];
    assert_eq!(Response::parse(&wire), Ok((1, Response::ReadInputRegisters(&[0xFF, 0xFF]))));
}

#[rstest]
#[case::illegal_function(0x01, ExceptionCode::IllegalFunction)]
#[case::illegal_address(0x02, ExceptionCode::IllegalDataAddress)]
#[case::illegal_value(0x03, ExceptionCode::IllegalDataValue)]
#[case::device_failure(0x04, ExceptionCode::ServerDeviceFailure)]
#[case::acknowledge(0x05, ExceptionCode::Acknowledge)]
#[case::busy(0x06, ExceptionCode::ServerDeviceBusy)]
#[case::parity(0x08, ExceptionCode::MemoryParityError)]
#[case::gateway_path(0x0A, ExceptionCode::GatewayPathUnavailable)]
#[case::gateway_target(0x0B, ExceptionCode::GatewayTargetFailedToRespond)]
#[case::unknown(0x07, ExceptionCode::Unknown(0x07))]
fn exception_codes(#[case] raw: u8, #[case] code: ExceptionCode) {
    assert_eq!(ExceptionCode::from(raw), code);
    assert_eq!(code.as_raw(), raw);
}

#[rstest]
#[case::crc(&[0x01, 0x04, 0x02, 0xFF, 0xFF, 0xB8, 0x81], CodecError::Crc)]
#[case::too_short(&[0x01, 0x83], CodecError::TooShort)]
fn response_parse_errors_raw(#[case] wire: &[u8], #[case] e: CodecError) {
    assert_eq!(Response::parse(wire), Err(e));
}

#[rstest]
#[case::unknown_function(&[0x01, 0x2B, 0x00], CodecError::UnknownFunction(0x2B))]
#[case::byte_count_vs_length(&[0x01, 0x03, 0x04, 0x00, 0x01], CodecError::Length { expected: 9, found: 7 })]
#[case::odd_register_bytes(&[0x01, 0x03, 0x01, 0x00], CodecError::ByteCount)]
#[case::coil_value(&[0x01, 0x05, 0x00, 0x01, 0x12, 0x34], CodecError::CoilValue(0x1234))]
#[case::exception_too_long(&[0x01, 0x83, 0x02, 0x00], CodecError::Length { expected: 5, found: 6 })]
#[case::write_echo_short(&[0x01, 0x06, 0x00, 0x01, 0x00], CodecError::Length { expected: 8, found: 7 })]
fn response_parse_errors(#[case] body: &[u8], #[case] e: CodecError) {
    assert_eq!(Response::parse(&adu(body)), Err(e));
}

#[rstest]
#[case::count_zero(&[0x01, 0x03, 0x00, 0x00, 0x00, 0x00], CodecError::Count(0))]
#[case::count_too_big(&[0x01, 0x03, 0x00, 0x00, 0x00, 0x7E], CodecError::Count(126))]
#[case::byte_count(&[0x01, 0x10, 0x00, 0x00, 0x00, 0x02, 0x02, 0x00, 0x01], CodecError::ByteCount)]
#[case::coil_value(&[0x01, 0x05, 0x00, 0x00, 0x00, 0x01], CodecError::CoilValue(1))]
#[case::unknown(&[0x01, 0x07, 0x00, 0x00, 0x00, 0x01], CodecError::UnknownFunction(7))]
fn request_parse_errors(#[case] body: &[u8], #[case] e: CodecError) {
    assert_eq!(Request::parse(&adu(body)), Err(e));
}

#[rstest]
#[case::count_zero(Request::ReadCoils { address: 0, count: 0 }, CodecError::Count(0))]
#[case::too_many_registers(Request::ReadInputRegisters { address: 0, count: 126 }, CodecError::Count(126))]
#[case::bits_mismatch(Request::WriteMultipleCoils { address: 0, count: 9, bits: &[0] }, CodecError::ByteCount)]
#[case::odd_values(Request::WriteMultipleRegisters { address: 0, values: &[0, 1, 2] }, CodecError::ByteCount)]
#[case::no_values(Request::WriteMultipleRegisters { address: 0, values: &[] }, CodecError::Count(0))]
fn request_emit_errors(#[case] request: Request<'static>, #[case] e: CodecError) {
    assert_eq!(request.emit(1, &mut [0u8; ADU_CAPACITY]), Err(e));
}

#[test]
fn emit_needs_room() {
    let r = Request::ReadCoils { address: 0, count: 1 };
    assert_eq!(r.emit(1, &mut [0u8; 7]), Err(CodecError::BufferTooSmall { needed: 8 }));
}

#[rstest]
#[case::read_bits(Request::ReadCoils { address: 0, count: 10 }, Response::ReadCoils(&[0, 0]), true)]
#[case::read_bits_short(Request::ReadCoils { address: 0, count: 10 }, Response::ReadCoils(&[0]), false)]
#[case::read_regs(Request::ReadHoldingRegisters { address: 0, count: 2 }, Response::ReadHoldingRegisters(&[0, 1, 0, 2]), true)]
#[case::wrong_function(Request::ReadHoldingRegisters { address: 0, count: 1 }, Response::ReadInputRegisters(&[0, 1]), false)]
#[case::echo(Request::WriteSingleRegister { address: 5, value: 7 }, Response::WriteSingleRegister { address: 5, value: 7 }, true)]
#[case::echo_wrong(Request::WriteSingleRegister { address: 5, value: 7 }, Response::WriteSingleRegister { address: 5, value: 8 }, false)]
#[case::coil_echo(Request::WriteSingleCoil { address: 1, value: true }, Response::WriteSingleCoil { address: 1, value: true }, true)]
#[case::coils(Request::WriteMultipleCoils { address: 3, count: 9, bits: &[0, 0] }, Response::WriteMultipleCoils { address: 3, count: 9 }, true)]
#[case::regs(Request::WriteMultipleRegisters { address: 3, values: &[0, 0] }, Response::WriteMultipleRegisters { address: 3, count: 1 }, true)]
#[case::regs_count(Request::WriteMultipleRegisters { address: 3, values: &[0, 0] }, Response::WriteMultipleRegisters { address: 3, count: 2 }, false)]
#[case::exception(Request::ReadCoils { address: 0, count: 1 }, Response::Exception { function: 1, code: ExceptionCode::IllegalFunction }, false)]
fn answers(#[case] request: Request<'static>, #[case] response: Response<'static>, #[case] yes: bool) {
    assert_eq!(response.answers(&request), yes);
}

#[rstest]
#[case::empty(&[], Ok(None))]
#[case::unit_only(&[1], Ok(None))]
#[case::read_needs_count(&[1, 3], Ok(None))]
#[case::exception(&[1, 0x83], Ok(Some(5)))]
#[case::write(&[1, 6], Ok(Some(8)))]
#[case::unknown(&[1, 0x2B], Err(CodecError::UnknownFunction(0x2B)))]
#[case::longest(&[1, 3, 250], Ok(Some(255)))]
#[case::impossible(&[1, 3, 251], Err(CodecError::ByteCount))]
fn response_len_cases(#[case] prefix: &[u8], #[case] len: Result<Option<usize>, CodecError>) {
    assert_eq!(response_len(prefix), len);
}

#[test]
fn function_codes() {
    for code in 0..=255u8 {
        match Function::try_from(code) {
            Ok(f) => assert_eq!(u8::from(f), code),
            Err(e) => assert_eq!(e, CodecError::UnknownFunction(code)),
        }
    }
    assert_eq!(Function::ReadCoils.data_len(9), 2);
    assert_eq!(Function::ReadInputRegisters.data_len(9), 18);
}

proptest! {
    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
        let _ = Request::parse(&bytes);
        let _ = Response::parse(&bytes);
        let _ = response_len(&bytes);
        let _ = request_len(&bytes);
    }

    // On what `response_len` delimits, `check_delimited_response` judges as `parse` does.
    #[test]
    fn delimited_response_check_is_parse(
        body in proptest::collection::vec(any::<u8>(), 3..260),
        code in prop_oneof![1u8..=6, Just(0x0F), Just(0x10), 0x80u8..=0xFF],
        bad_crc in any::<bool>(),
    ) {
        let mut body = body;
        body[1] = code;
        if code == 5 && body.len() > 5 && body[0] % 2 == 0 {
            // Valid coil values, half the time.
            body[4] = if body[5] % 2 == 0 { 0xFF } else { 0x00 };
            body[5] = 0;
        }
        if let Ok(Some(len)) = response_len(&body) {
            if len <= body.len() + 2 {
                let mut wire = adu(&body[..len - 2]);
                if bad_crc {
                    wire[len - 1] ^= 1;
                }
                prop_assert_eq!(check_delimited_response(&wire), Response::parse(&wire).map(|_| ()));
            }
        }
    }

    #[test]
    fn valid_crc_bodies_round_trip(body in proptest::collection::vec(any::<u8>(), 0..20)) {
        let wire = adu(&body);
        let mut out = [0u8; ADU_CAPACITY];
        if let Ok((unit, r)) = Response::parse(&wire) {
            let n = r.emit(unit, &mut out).unwrap();
            prop_assert_eq!(&out[..n], wire.as_slice());
        }
        if let Ok((unit, r)) = Request::parse(&wire) {
            let n = r.emit(unit, &mut out).unwrap();
            prop_assert_eq!(&out[..n], wire.as_slice());
        }
    }
}
