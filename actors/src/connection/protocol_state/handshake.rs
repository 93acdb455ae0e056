//! The handshake: the encrypted channel's (with a secret), `Hello` (protocol version,
//! name), the HMAC challenge and `Auth`, then `Welcome` with the set layout and the asset
//! manifest.

use super::{Action, Phase, ProtocolState};
use crate::wire::auth;
use crate::wire::channel::{respond, Psk};
use crate::wire::integrity::ResultKey;
use crate::wire::protocol::{MasterMsg, PROTOCOL_VERSION};
use crate::wire::rejection::Rejection;

/// Longest worker name accepted.
pub const MAX_NAME_LEN: usize = 256;

impl ProtocolState {
    /// `Handshake`: the worker's first message of the encrypted channel answered, when
    /// this master has a secret and the worker proves the same one; every frame after the
    /// answer is encrypted. No downgrade: a master without a secret refuses it, since the
    /// worker asked for what it cannot give.
    pub(super) fn on_channel(
        &mut self,
        protocol: u32,
        noise: &[u8],
        out: &mut Vec<Action>,
    ) -> Result<(), Rejection> {
        if protocol != PROTOCOL_VERSION {
            return Err(Rejection::Version { worker: protocol, master: PROTOCOL_VERSION });
        }
        let Some(secret) = &self.config.secret else { return Err(Rejection::NotEncrypting) };
        let (answer, keys) =
            respond(&Psk::derive(secret), noise).map_err(|_| Rejection::WrongSecret)?;
        self.encrypted = true;
        out.push(Action::Send(MasterMsg::Handshake { noise: answer }));
        out.push(Action::Encrypt(keys));
        Ok(())
    }

    /// `Hello`: the worker's name and cores noted, its protocol version checked, and the
    /// challenge sent. With a secret, only inside the encrypted channel.
    pub(super) fn on_hello(
        &mut self,
        protocol: u32,
        name: &str,
        cores: u32,
        out: &mut Vec<Action>,
    ) -> Result<(), Rejection> {
        self.name = sanitize(name);
        self.cores = cores;
        if protocol != PROTOCOL_VERSION {
            return Err(Rejection::Version { worker: protocol, master: PROTOCOL_VERSION });
        }
        if self.config.secret.is_some() && !self.encrypted {
            return Err(Rejection::NoSecret);
        }
        if name.is_empty() || name.len() > MAX_NAME_LEN {
            return Err(Rejection::Name { max: MAX_NAME_LEN });
        }
        let nonce = auth::nonce();
        self.phase = Phase::Auth { nonce };
        let auth_required = self.config.secret.is_some();
        out.push(Action::Send(MasterMsg::Challenge { nonce, auth_required }));
        Ok(())
    }

    /// `Auth`: the MAC checked against the challenge's `nonce` when a secret is set (inside
    /// the channel, a second proof of the secret); the worker is welcomed and how its
    /// results are checked decided (by the channel, or by their checksum).
    pub(super) fn on_auth(
        &mut self,
        nonce: [u8; 32],
        mac: Option<[u8; 32]>,
        out: &mut Vec<Action>,
    ) -> Result<(), Rejection> {
        if let Some(secret) = &self.config.secret {
            match mac {
                None => return Err(Rejection::NoSecret),
                Some(m) if !auth::verify(secret, &nonce, &m) => return Err(Rejection::WrongSecret),
                Some(_) => {}
            }
        }
        let key = ResultKey::for_connection(self.encrypted, &nonce);
        self.phase = Phase::Work { key };
        self.welcomed = true;
        out.push(Action::Joined);
        out.push(Action::Send(MasterMsg::Welcome {
            worker_id: self.id,
            sets: self.config.sets.config(),
            assets: self.config.assets.manifest().to_vec(),
        }));
        Ok(())
    }
}

/// A name safe to put in logs (no control characters).
fn sanitize(name: &str) -> String {
    name.chars().take(MAX_NAME_LEN).map(|c| if c.is_control() { '?' } else { c }).collect()
}
