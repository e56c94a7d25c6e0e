//! Users and their roles, with Argon2 password hashes in a local TOML file.
//!
//! ```toml
//! [[users]]
//! name = "maria"
//! role = "approver"
//! password_hash = "$argon2id$v=19$m=19456,t=2,p=1$..."
//! ```
//!
//! No password is ever stored or logged; only the PHC hash string is kept.

use std::path::Path;

use argon2::Argon2;
use argon2::password_hash::phc::PasswordHash;
use argon2::password_hash::{PasswordHasher, PasswordVerifier};

/// What a user may do.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Requests compensation pushes.
    Operator,
    /// Approves them (and may also request).
    Approver,
}

/// One user.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct User {
    /// Login name.
    pub name: String,
    /// Role.
    pub role: Role,
    /// Argon2 PHC string.
    pub password_hash: String,
}

/// The users file.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Credentials {
    /// Every user.
    #[serde(default)]
    pub users: Vec<User>,
}

/// Errors of the credential store.
#[derive(Debug, thiserror::Error)]
pub enum CredentialError {
    /// The file could not be read or written.
    // The operating system's error is part of the message and not also its `source`: the
    // command line prints an error's whole chain, which then said it twice.
    #[error("{path}: {error}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's error.
        error: std::io::Error,
    },
    /// The file is not valid TOML of this shape.
    #[error("{path}: {message}")]
    Format {
        /// The file.
        path: String,
        /// The parser's message.
        message: String,
    },
    /// No such user, or the password is wrong (deliberately one message for both).
    #[error("unknown user or wrong password for `{0}`")]
    Rejected(String),
    /// The user exists but lacks the role.
    #[error("`{user}` is a {role:?}, not an approver")]
    NotApprover {
        /// The user.
        user: String,
        /// Their role.
        role: Role,
    },
    /// Hashing failed.
    #[error("password hashing failed: {0}")]
    Hashing(String),
}

impl Credentials {
    /// Loads the users file.
    pub fn load(path: &Path) -> Result<Credentials, CredentialError> {
        let text = std::fs::read_to_string(path).map_err(|error| CredentialError::Io {
            path: path.display().to_string(),
            error,
        })?;
        toml::from_str(&text).map_err(|e| CredentialError::Format {
            path: path.display().to_string(),
            message: e.to_string(),
        })
    }

    /// Loads the users file, or an empty store when it does not exist yet.
    pub fn load_or_empty(path: &Path) -> Result<Credentials, CredentialError> {
        if path.exists() {
            Self::load(path)
        } else {
            Ok(Credentials::default())
        }
    }

    /// Writes the users file.
    pub fn save(&self, path: &Path) -> Result<(), CredentialError> {
        let text = toml::to_string(self).map_err(|e| CredentialError::Format {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        std::fs::write(path, text).map_err(|error| CredentialError::Io {
            path: path.display().to_string(),
            error,
        })
    }

    /// Adds a user or replaces the password and role of an existing one.
    pub fn set_user(
        &mut self,
        name: &str,
        role: Role,
        password: &str,
    ) -> Result<(), CredentialError> {
        let password_hash = hash_password(password)?;
        match self.users.iter_mut().find(|u| u.name == name) {
            Some(user) => {
                user.role = role;
                user.password_hash = password_hash;
            }
            None => self.users.push(User {
                name: name.to_string(),
                role,
                password_hash,
            }),
        }
        Ok(())
    }

    /// Checks a user's password; returns their role.
    pub fn authenticate(&self, name: &str, password: &str) -> Result<Role, CredentialError> {
        let rejected = || CredentialError::Rejected(name.to_string());
        let user = self
            .users
            .iter()
            .find(|u| u.name == name)
            .ok_or_else(rejected)?;
        let hash = PasswordHash::new(&user.password_hash).map_err(|_| rejected())?;
        Argon2::default()
            .verify_password(password.as_bytes(), &hash)
            .map_err(|_| rejected())?;
        Ok(user.role)
    }

    /// Checks that `name` is an approver with this password.
    pub fn authenticate_approver(&self, name: &str, password: &str) -> Result<(), CredentialError> {
        match self.authenticate(name, password)? {
            Role::Approver => Ok(()),
            role => Err(CredentialError::NotApprover {
                user: name.to_string(),
                role,
            }),
        }
    }
}

/// Hashes a password with Argon2id and a random salt into a PHC string.
pub fn hash_password(password: &str) -> Result<String, CredentialError> {
    Argon2::default()
        .hash_password(password.as_bytes())
        .map(|hash| hash.to_string())
        .map_err(|e| CredentialError::Hashing(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn approver_is_checked_against_the_hash_and_the_role() {
        let mut store = Credentials::default();
        store
            .set_user("maria", Role::Approver, "correct horse")
            .unwrap();
        store
            .set_user("otto", Role::Operator, "battery staple")
            .unwrap();
        let text = toml::to_string(&store).unwrap();
        assert!(!text.contains("correct horse"), "no plaintext on disk");
        assert!(text.contains("$argon2id$"));
        let store: Credentials = toml::from_str(&text).unwrap();
        store
            .authenticate_approver("maria", "correct horse")
            .unwrap();
        assert!(matches!(
            store.authenticate_approver("maria", "wrong"),
            Err(CredentialError::Rejected(_))
        ));
        assert!(matches!(
            store.authenticate_approver("otto", "battery staple"),
            Err(CredentialError::NotApprover { .. })
        ));
        assert!(matches!(
            store.authenticate_approver("nobody", "x"),
            Err(CredentialError::Rejected(_))
        ));
    }
}
