//! The signed firmware image of the firmware update over DeviceNet (issue 31; the design page
//! `docs/src/development/firmware-update.md`, "The image and its signature").
//!
//! A signed file is the firmware's flat binary (the **image**) followed by a 128-byte
//! [`Trailer`]. The image carries an [`ImageInfo`] block at offset 0x200 (board ID, firmware
//! revision); the trailer carries the image length, copies of the board and revision, the
//! [`KeyId`] of the signing key and an Ed25519 signature over SHA-512(image): the scheme of
//! embassy-boot's `verify_and_mark_updated` with its `ed25519-salty` feature, computed here with
//! the same crate (`salty`), so the firmware, the bootloader and the host tools agree.
//!
//! | layer | items |
//! |---|---|
//! | formats | [`ImageInfo`] ([`INFO_OFFSET`], [`INFO_LEN`]), [`Trailer`] ([`TRAILER_LEN`]), [`KeyId`] |
//! | checks | [`verify`] (a whole image in memory), [`ImageHasher`] + [`verify_digest`] (an image read piece by piece, e.g. from flash) |
//! | signing | `sign` (feature `sign`, host only) |
//!
//! Features: `std` (`std::error::Error` on the errors), `sign` (signing with a secret seed).
//!
//! No function here panics on any input; no allocation; no `unsafe`.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![cfg_attr(
    not(test),
    deny(clippy::indexing_slicing, clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]

mod info;
mod trailer;

pub use info::{ImageInfo, InfoError, INFO_FORMAT, INFO_LEN, INFO_MAGIC, INFO_OFFSET};
pub use trailer::{Trailer, TrailerError, TRAILER_FORMAT, TRAILER_LEN, TRAILER_MAGIC};

/// The largest image: one 128 KiB flash sector (ACTIVE) less the trailer, 130,944 bytes (the
/// design page, "Flash layout").
pub const MAX_IMAGE_LEN: usize = 128 * 1024 - TRAILER_LEN;

/// A firmware revision, major and minor.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Revision {
    /// The major revision.
    pub major: u8,
    /// The minor revision.
    pub minor: u8,
}

impl core::fmt::Display for Revision {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{}.{}", self.major, self.minor)
    }
}

/// The ID of an Ed25519 public key: the first 8 bytes of SHA-512 of its 32 bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct KeyId(pub [u8; 8]);

impl KeyId {
    /// The ID of a public key.
    #[must_use]
    pub fn of(public_key: &[u8; 32]) -> Self {
        let digest = salty::Sha512::new().updated(public_key).finalize();
        let mut id = [0u8; 8];
        for (to, from) in id.iter_mut().zip(digest) {
            *to = from;
        }
        Self(id)
    }
}

impl core::fmt::Display for KeyId {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        self.0.iter().try_for_each(|b| write!(f, "{b:02x}"))
    }
}

/// Why a signature check failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum VerifyError {
    /// The image's length is not the trailer's.
    #[error("the image is {image} bytes, the trailer says {trailer}")]
    LengthMismatch {
        /// The trailer's image length.
        trailer: u32,
        /// The image's length.
        image: usize,
    },
    /// The trailer names another key than the one checked against.
    #[error("the image is signed with key {signed}, this device checks key {expected}")]
    AnotherKey {
        /// The trailer's key ID.
        signed: KeyId,
        /// The ID of the key the check uses.
        expected: KeyId,
    },
    /// The public key is not a point on the curve.
    #[error("the public key is not a valid Ed25519 key")]
    BadPublicKey,
    /// The signature does not match the image.
    #[error("the signature does not match the image")]
    BadSignature,
}

/// SHA-512 of an image read piece by piece (from flash, in chunks), for [`verify_digest`].
pub struct ImageHasher {
    sha: salty::Sha512,
    len: usize,
}

impl Default for ImageHasher {
    fn default() -> Self {
        Self::new()
    }
}

impl ImageHasher {
    /// An empty hasher.
    #[must_use]
    pub fn new() -> Self {
        Self { sha: salty::Sha512::new(), len: 0 }
    }

    /// Adds the image's next bytes.
    pub fn update(&mut self, bytes: &[u8]) {
        self.sha.update(bytes);
        self.len = self.len.saturating_add(bytes.len());
    }

    /// The number of bytes hashed so far.
    #[must_use]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no byte has been hashed yet.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The digest and the number of bytes it covers.
    #[must_use]
    pub fn finalize(self) -> ([u8; 64], usize) {
        (self.sha.finalize(), self.len)
    }
}

/// Checks a signed image given its SHA-512 `digest` over `image_len` bytes: the length against
/// the trailer's, the trailer's key ID against `public_key`'s, then the Ed25519 signature over
/// the digest (as embassy-boot's `verify_and_mark_updated` does).
///
/// # Errors
/// The first check that failed, in that order.
pub fn verify_digest(
    digest: &[u8; 64],
    image_len: usize,
    trailer: &Trailer,
    public_key: &[u8; 32],
) -> Result<(), VerifyError> {
    if trailer.image_len as usize != image_len {
        return Err(VerifyError::LengthMismatch { trailer: trailer.image_len, image: image_len });
    }
    let expected = KeyId::of(public_key);
    if trailer.key_id != expected {
        return Err(VerifyError::AnotherKey { signed: trailer.key_id, expected });
    }
    let key = salty::PublicKey::try_from(public_key).map_err(|_| VerifyError::BadPublicKey)?;
    let signature = salty::Signature::from(&trailer.signature);
    key.verify(digest, &signature).map_err(|_| VerifyError::BadSignature)
}

/// Checks a signed image held in memory; see [`verify_digest`].
///
/// # Errors
/// As [`verify_digest`].
pub fn verify(image: &[u8], trailer: &Trailer, public_key: &[u8; 32]) -> Result<(), VerifyError> {
    let mut hasher = ImageHasher::new();
    hasher.update(image);
    let (digest, len) = hasher.finalize();
    verify_digest(&digest, len, trailer, public_key)
}

/// Why an image cannot be signed.
#[cfg(feature = "sign")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SignError {
    /// The image has no valid image-info block.
    #[error(transparent)]
    Info(#[from] InfoError),
    /// The image is empty or larger than [`MAX_IMAGE_LEN`].
    #[error("the image is {0} bytes; a signed image is 1 to 130944 bytes")]
    ImageLength(usize),
}

/// Signs an image with the secret `seed` (32 bytes, RFC 8032's secret key): the trailer that
/// follows it in the signed file, its board and revision copied from the image-info block.
///
/// # Errors
/// [`SignError`] when the image has no image-info block or a length no device takes.
#[cfg(feature = "sign")]
pub fn sign(image: &[u8], seed: &[u8; 32]) -> Result<Trailer, SignError> {
    let info = ImageInfo::parse(image)?;
    let image_len = match u32::try_from(image.len()) {
        Ok(len) if len > 0 && image.len() <= MAX_IMAGE_LEN => len,
        _ => return Err(SignError::ImageLength(image.len())),
    };
    let keypair = salty::Keypair::from(seed);
    let mut hasher = ImageHasher::new();
    hasher.update(image);
    let (digest, _) = hasher.finalize();
    Ok(Trailer {
        image_len,
        board_id: info.board_id,
        revision: info.revision,
        key_id: KeyId::of(keypair.public.as_bytes()),
        signature: keypair.sign(&digest).to_bytes(),
    })
}

#[cfg(test)]
mod tests;
