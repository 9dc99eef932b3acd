//! The checks against the repository's TEST ONLY keypair (`contrib/keys/`) and against a
//! signature made by another implementation (Python `cryptography` 48.0.0, OpenSSL's Ed25519).

use super::*;
use rstest::rstest;

const PUBLIC: &[u8; 32] = include_bytes!("../../contrib/keys/test-ed25519.public");
const SECRET: &[u8; 32] = include_bytes!("../../contrib/keys/test-ed25519.secret");

/// The key ID of the test public key, SHA-512 by Python's `hashlib`.
const TEST_KEY_ID: [u8; 8] = [0x53, 0x6c, 0x52, 0x52, 0x7d, 0xd7, 0x67, 0x49];

/// `Ed25519PrivateKey.from_private_bytes(seed).sign(sha512(image))` in Python `cryptography`
/// 48.0.0 over [`image`], with the test seed.
const PYTHON_SIGNATURE: [u8; 64] = [
    0x31, 0xb1, 0x23, 0x6e, 0x77, 0x2a, 0x39, 0xd6, 0x11, 0x6e, 0x49, 0xcd, 0xa0, 0xf9, 0xd3, 0x03, 0x4f,
    0x93, 0x4a, 0x3f, 0xdd, 0x8b, 0x9f, 0xed, 0xf0, 0x0a, 0x02, 0xa5, 0xb5, 0xb7, 0xe5, 0x48, 0xeb, 0xb6,
    0x7c, 0x17, 0xe5, 0x53, 0x6b, 0x27, 0x5b, 0x89, 0x89, 0xa0, 0x6d, 0xb2, 0x0e, 0xa6, 0x50, 0xfa, 0xb7,
    0xe6, 0x84, 0xb2, 0x71, 0x54, 0xa9, 0x31, 0x27, 0x74, 0xf7, 0xda, 0x05, 0x05,
];

/// 0x300 bytes `(7i + 3) mod 256` with the block of board 1, revision 2.3 at 0x200 (the image
/// the Python signature covers).
fn image() -> [u8; 0x300] {
    let mut image = [0u8; 0x300];
    for (i, b) in image.iter_mut().enumerate() {
        *b = ((i * 7 + 3) % 256) as u8;
    }
    let info = ImageInfo { board_id: 1, revision: Revision { major: 2, minor: 3 } };
    image[INFO_OFFSET..INFO_OFFSET + INFO_LEN].copy_from_slice(&info.to_bytes());
    image
}

#[test]
fn key_id_is_the_head_of_sha512_of_the_key() {
    assert_eq!(KeyId::of(PUBLIC), KeyId(TEST_KEY_ID));
    assert_eq!(KeyId(TEST_KEY_ID).to_string(), "536c52527dd76749");
}

#[test]
fn sign_matches_another_implementation() {
    let trailer = sign(&image(), SECRET).unwrap();
    // Ed25519 is deterministic: the same seed and message give the same signature.
    assert_eq!(trailer.signature, PYTHON_SIGNATURE);
    assert_eq!(trailer.image_len, 0x300);
    assert_eq!(trailer.board_id, 1);
    assert_eq!(trailer.revision, Revision { major: 2, minor: 3 });
    assert_eq!(trailer.key_id, KeyId(TEST_KEY_ID));
    assert_eq!(verify(&image(), &trailer, PUBLIC), Ok(()));
}

#[test]
fn verify_accepts_another_implementations_signature() {
    let trailer = Trailer {
        image_len: 0x300,
        board_id: 1,
        revision: Revision { major: 2, minor: 3 },
        key_id: KeyId(TEST_KEY_ID),
        signature: PYTHON_SIGNATURE,
    };
    assert_eq!(verify(&image(), &trailer, PUBLIC), Ok(()));
}

#[rstest]
#[case::first_byte(0)]
#[case::info_block(INFO_OFFSET + 8)]
#[case::last_byte(0x2FF)]
fn verify_refuses_a_changed_image(#[case] at: usize) {
    let trailer = sign(&image(), SECRET).unwrap();
    let mut image = image();
    image[at] ^= 0x01;
    assert_eq!(verify(&image, &trailer, PUBLIC), Err(VerifyError::BadSignature));
}

#[test]
fn verify_refuses_a_changed_signature() {
    let mut trailer = sign(&image(), SECRET).unwrap();
    trailer.signature[10] ^= 0x80;
    assert_eq!(verify(&image(), &trailer, PUBLIC), Err(VerifyError::BadSignature));
}

#[test]
fn verify_refuses_another_length_before_hashing_the_signature() {
    let trailer = sign(&image(), SECRET).unwrap();
    assert_eq!(
        verify(&image()[..0x2FF], &trailer, PUBLIC),
        Err(VerifyError::LengthMismatch { trailer: 0x300, image: 0x2FF })
    );
}

#[test]
fn verify_refuses_another_key() {
    let other_seed = [7u8; 32];
    let trailer = sign(&image(), &other_seed).unwrap();
    let other_public = salty::Keypair::from(&other_seed).public.to_bytes();
    assert_eq!(verify(&image(), &trailer, &other_public), Ok(()));
    assert_eq!(
        verify(&image(), &trailer, PUBLIC),
        Err(VerifyError::AnotherKey { signed: KeyId::of(&other_public), expected: KeyId(TEST_KEY_ID) })
    );
}

#[test]
fn hashing_in_pieces_gives_the_whole_digest() {
    let trailer = sign(&image(), SECRET).unwrap();
    let mut hasher = ImageHasher::new();
    for chunk in image().chunks(128) {
        hasher.update(chunk);
    }
    let (digest, len) = hasher.finalize();
    assert_eq!(len, 0x300);
    assert_eq!(verify_digest(&digest, len, &trailer, PUBLIC), Ok(()));
}

#[rstest]
#[case::no_info(&[0u8; 0x210][..], SignError::Info(InfoError::BadMagic))]
#[case::short(&[0u8; 16][..], SignError::Info(InfoError::TooShort { len: 16 }))]
fn sign_refuses_an_image_without_info(#[case] image: &[u8], #[case] error: SignError) {
    assert_eq!(sign(image, SECRET), Err(error));
}

#[test]
fn sign_refuses_an_image_above_the_largest() {
    let mut big = [0u8; MAX_IMAGE_LEN + 1];
    big[..0x300].copy_from_slice(&image());
    assert_eq!(sign(&big, SECRET), Err(SignError::ImageLength(MAX_IMAGE_LEN + 1)));
    assert!(sign(&big[..MAX_IMAGE_LEN], SECRET).is_ok());
}

#[test]
fn revision_displays_as_major_dot_minor() {
    assert_eq!(Revision { major: 1, minor: 2 }.to_string(), "1.2");
}

mod properties {
    //! No input makes a parser panic; what is written reads back.

    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn trailer_parse_takes_any_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
            let _ = Trailer::parse(&bytes);
        }

        #[test]
        fn info_parse_takes_any_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..0x220)) {
            let _ = ImageInfo::parse(&bytes);
        }

        #[test]
        fn a_trailer_reads_back(
            image_len in 1u32..=MAX_IMAGE_LEN as u32,
            board_id: u16,
            major: u8,
            minor: u8,
            key_id: [u8; 8],
            sig in proptest::collection::vec(any::<u8>(), 64),
        ) {
            let t = Trailer {
                image_len,
                board_id,
                revision: Revision { major, minor },
                key_id: KeyId(key_id),
                signature: sig.try_into().unwrap(),
            };
            prop_assert_eq!(Trailer::parse(&t.to_bytes()), Ok(t));
        }

        #[test]
        fn an_info_block_reads_back(board_id: u16, major: u8, minor: u8) {
            let info = ImageInfo { board_id, revision: Revision { major, minor } };
            prop_assert_eq!(ImageInfo::from_bytes(&info.to_bytes()), Ok(info));
        }
    }
}
