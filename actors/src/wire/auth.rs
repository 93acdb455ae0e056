//! Challenge-response authentication with a shared secret (docs/design.md, decision 5),
//! and the secret file.
//!
//! The master sends a fresh random nonce; the worker answers HMAC-SHA256(secret, nonce);
//! the master recomputes and compares in constant time. The secret itself never travels,
//! and a recorded answer is useless against the next nonce.

use std::path::{Path, PathBuf};

use hmac::{Hmac, Mac};
use rand::RngCore;
use sha2::Sha256;
use thiserror::Error;

type HmacSha256 = Hmac<Sha256>;

/// Bytes of a nonce and of a MAC.
pub const NONCE_LEN: usize = 32;

/// A secret shorter than this is warned about when read: one recorded handshake of the
/// encrypted channel lets an eavesdropper test guesses of the secret offline.
pub const SHORT_SECRET: usize = 16;

/// Errors reading a secret file.
#[derive(Debug, Error)]
pub enum SecretError {
    #[error("cannot read secret file {path}: {source}")]
    Read { path: PathBuf, source: std::io::Error },
    #[error("secret file {path} is empty")]
    Empty { path: PathBuf },
}

/// A fresh nonce from the operating system's CSPRNG.
pub fn nonce() -> [u8; NONCE_LEN] {
    let mut n = [0u8; NONCE_LEN];
    rand::rngs::OsRng.fill_bytes(&mut n);
    n
}

/// HMAC-SHA256(secret, nonce): what the worker sends back.
pub fn mac(secret: &[u8], nonce: &[u8; NONCE_LEN]) -> [u8; 32] {
    let mut m = keyed(secret);
    m.update(nonce);
    m.finalize().into_bytes().into()
}

/// True when `mac` is HMAC-SHA256(secret, nonce); compares in constant time.
pub fn verify(secret: &[u8], nonce: &[u8; NONCE_LEN], mac: &[u8; 32]) -> bool {
    let mut m = keyed(secret);
    m.update(nonce);
    m.verify_slice(mac).is_ok()
}

/// Reads a secret file; a single trailing newline (as editors add) is not part of it.
pub fn read_secret_file(path: &Path) -> Result<Vec<u8>, SecretError> {
    let mut bytes = std::fs::read(path)
        .map_err(|source| SecretError::Read { path: path.to_owned(), source })?;
    if bytes.last() == Some(&b'\n') {
        bytes.pop();
        if bytes.last() == Some(&b'\r') {
            bytes.pop();
        }
    }
    if bytes.is_empty() {
        return Err(SecretError::Empty { path: path.to_owned() });
    }
    if bytes.len() < SHORT_SECRET {
        tracing::warn!(path = %path.display(), bytes = bytes.len(),
            "the shared secret is short: one recorded handshake lets an eavesdropper test guesses of it offline; use 32 random bytes (head -c 32 /dev/urandom | base64)");
    }
    Ok(bytes)
}

fn keyed(secret: &[u8]) -> HmacSha256 {
    // HMAC accepts keys of any length, so this cannot fail.
    <HmacSha256 as Mac>::new_from_slice(secret).expect("HMAC takes keys of any length")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn right_secret_verifies_and_wrong_one_does_not() {
        let n = nonce();
        let m = mac(b"open sesame", &n);
        assert!(verify(b"open sesame", &n, &m));
        assert!(!verify(b"open sesamE", &n, &m));
        let mut flipped = m;
        flipped[31] ^= 1;
        assert!(!verify(b"open sesame", &n, &flipped));
    }

    #[test]
    fn a_mac_does_not_answer_another_nonce() {
        let (a, b) = (nonce(), nonce());
        assert_ne!(a, b, "two nonces were equal");
        assert!(!verify(b"k", &b, &mac(b"k", &a)));
    }

    #[test]
    fn known_answer_rfc4231_case_2() {
        // RFC 4231 test case 2 uses a 28-byte message; check our keyed HMAC on it.
        let mut m = keyed(b"Jefe");
        m.update(b"what do ya want for nothing?");
        let out: [u8; 32] = m.finalize().into_bytes().into();
        assert_eq!(out[..4], [0x5b, 0xdc, 0xc1, 0x46]);
    }

    #[test]
    fn secret_file_strips_one_newline_and_rejects_empty() {
        let dir = std::env::temp_dir().join(format!("gl-secret-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let p = dir.join("s");
        std::fs::write(&p, b"abc\n").expect("write");
        assert_eq!(read_secret_file(&p).expect("read"), b"abc");
        std::fs::write(&p, b"\n").expect("write");
        assert!(matches!(read_secret_file(&p), Err(SecretError::Empty { .. })));
        assert!(matches!(read_secret_file(&dir.join("missing")), Err(SecretError::Read { .. })));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
