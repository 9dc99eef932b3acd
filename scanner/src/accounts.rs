//! The console's accounts: a users file of names, roles and argon2 password hashes, and what each
//! role may do. The web console (`dnet-master ui --users FILE`), the OPC UA methods and the
//! Sparkplug DCMD handler all ask [`Users::verify`] who is calling and [`Role::may`] whether that
//! role may do it.
//!
//! ## The users file
//!
//! TOML, one `[[user]]` table per account; written by `dnet-master user add FILE NAME --role ROLE`
//! (mode 0600 on Unix: the hashes are not secrets, but they are a target for offline guessing):
//!
//! ```toml
//! [[user]]
//! name = "alice"
//! role = "operator"
//! hash = "$argon2id$v=19$m=19456,t=2,p=1$...$..."
//! ```
//!
//! Only the hash is stored, as an argon2 PHC string (argon2id, the crate's default cost: 19 MiB,
//! 2 passes, a random 16-byte salt); the password is never written. Unknown keys, a missing key, a
//! role that is not `viewer`, `operator` or `engineer`, a name used twice, a name with characters
//! other than letters, digits, `.`, `_`, `-` (or longer than [`MAX_NAME`]) and a hash that is not
//! a PHC string are errors naming the file and line ([`AccountsError`]).
//!
//! ## Roles
//!
//! | role | [`Action::View`] | [`Action::Operate`] | [`Action::Engineer`] |
//! |---|---|---|---|
//! | [`Role::Viewer`] | yes | no | no |
//! | [`Role::Operator`] | yes | yes | no |
//! | [`Role::Engineer`] | yes | yes | yes |
//!
//! ## Timing
//!
//! [`Users::verify`] of an unknown name checks the password against a hash of the same cost, so
//! the answer takes as long for a name that does not exist as for a wrong password: the time does
//! not tell which names exist. Nothing here panics on file contents.

use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use argon2::password_hash::{PasswordHasher, PasswordVerifier};
use argon2::Argon2;

/// The longest user name, in bytes.
pub const MAX_NAME: usize = 64;

/// The longest password accepted, in bytes (argon2 takes any length; a bound keeps a hostile login
/// request from costing more than a normal one).
pub const MAX_PASSWORD: usize = 1024;

/// The largest users file read, in bytes.
pub const MAX_FILE: u64 = 1 << 20;

/// What a request wants to do, from the least to the most privileged.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Action {
    /// Read: node table, values, frames, history, audit log.
    View,
    /// Operate the plant: write outputs, open and close breakers, set breaker parameters.
    Operate,
    /// Change devices and the scanner: Set attributes, configure devices, edit the scan list.
    Engineer,
}

impl Action {
    /// The action in words (`view`, `operate`, `engineer`), as refusals name it.
    pub fn name(self) -> &'static str {
        match self {
            Action::View => "view",
            Action::Operate => "operate",
            Action::Engineer => "engineer",
        }
    }
}

/// An account's role; each may do what the one before it may, and more (see the
/// [module docs](self)).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Role {
    /// Sees everything, commands nothing.
    Viewer,
    /// Also sends outputs and breaker commands (open, close, parameters).
    Operator,
    /// Also Sets attributes, configures devices and edits the scan list.
    Engineer,
}

impl Role {
    /// Every role, least privileged first.
    pub const ALL: [Role; 3] = [Role::Viewer, Role::Operator, Role::Engineer];

    /// Whether this role may do `action`.
    pub fn may(self, action: Action) -> bool {
        match action {
            Action::View => true,
            Action::Operate => matches!(self, Role::Operator | Role::Engineer),
            Action::Engineer => self == Role::Engineer,
        }
    }

    /// The role as the users file and the command line write it (`viewer`, `operator`,
    /// `engineer`).
    pub fn name(self) -> &'static str {
        match self {
            Role::Viewer => "viewer",
            Role::Operator => "operator",
            Role::Engineer => "engineer",
        }
    }

    /// The role named `text` (`viewer`, `operator`, `engineer`), if any.
    pub fn from_name(text: &str) -> Option<Role> {
        Role::ALL.into_iter().find(|r| r.name() == text)
    }
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Role {
    type Err = AccountsError;

    fn from_str(s: &str) -> Result<Role, AccountsError> {
        Role::from_name(s).ok_or_else(|| AccountsError::BadRole { role: s.to_string() })
    }
}

/// What went wrong with a users file or an account.
#[derive(Debug, thiserror::Error)]
pub enum AccountsError {
    /// The file cannot be read or written.
    #[error("users file {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The system's reason.
        source: std::io::Error,
    },
    /// The file is larger than [`MAX_FILE`].
    #[error("users file {}: {size} bytes, more than the {MAX_FILE} a users file may have", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size.
        size: u64,
    },
    /// The file's contents are wrong at a line (syntax, an unknown or missing key, a bad value).
    #[error("users file {}, line {line}: {message}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// 1-based line (0: the whole file).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A role name that is not `viewer`, `operator` or `engineer`.
    #[error("unknown role `{role}`: the roles are viewer, operator and engineer")]
    BadRole {
        /// The name given.
        role: String,
    },
    /// A user name that is empty, too long or has other characters than letters, digits, `.`,
    /// `_`, `-`.
    #[error("bad user name `{name}`: 1 to {MAX_NAME} letters, digits, `.`, `_` or `-`")]
    BadName {
        /// The name given.
        name: String,
    },
    /// An empty password, or one longer than [`MAX_PASSWORD`] bytes.
    #[error("the password is empty or longer than {MAX_PASSWORD} bytes")]
    BadPassword,
    /// `add` of a name the file has already.
    #[error("users file {}: user `{name}` exists already (remove it first)", path.display())]
    Exists {
        /// The file.
        path: PathBuf,
        /// The name.
        name: String,
    },
    /// `remove` of a name the file does not have.
    #[error("users file {}: no user `{name}`", path.display())]
    NoSuchUser {
        /// The file.
        path: PathBuf,
        /// The name.
        name: String,
    },
    /// argon2 could not hash (no random salt from the system).
    #[error("hashing the password: {0}")]
    Hash(String),
}

/// One account: its role and its argon2 PHC hash.
#[derive(Clone, PartialEq, Eq)]
pub struct Account {
    /// What the account may do.
    pub role: Role,
    /// The argon2 PHC string (`$argon2id$v=19$...`).
    pub hash: String,
}

impl fmt::Debug for Account {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Account").field("role", &self.role).finish_non_exhaustive()
    }
}

/// The accounts of a users file (see the [module docs](self)).
#[derive(Clone, Debug, Default)]
pub struct Users {
    path: PathBuf,
    accounts: BTreeMap<String, Account>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileRepr {
    #[serde(default)]
    user: Vec<toml::Spanned<UserRepr>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct UserRepr {
    name: toml::Spanned<String>,
    role: toml::Spanned<String>,
    hash: toml::Spanned<String>,
}

/// 1-based line of byte `at` in `text`.
fn line_of(text: &str, at: usize) -> usize {
    text.get(..at.min(text.len())).map_or(0, |b| b.matches('\n').count()) + 1
}

/// Whether `name` is a valid user name.
pub fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= MAX_NAME
        && name.bytes().all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'_' | b'-'))
}

fn argon2() -> Argon2<'static> {
    Argon2::default()
}

/// The hash checked for a name that does not exist (same cost as a real one).
fn decoy_hash() -> &'static str {
    static DECOY: OnceLock<String> = OnceLock::new();
    DECOY.get_or_init(|| hash_password("not a password of anyone").unwrap_or_default())
}

/// The argon2id PHC string of `password` with a fresh random salt.
pub fn hash_password(password: &str) -> Result<String, AccountsError> {
    if password.is_empty() || password.len() > MAX_PASSWORD {
        return Err(AccountsError::BadPassword);
    }
    argon2()
        .hash_password(password.as_bytes())
        .map(|h| h.to_string())
        .map_err(|e| AccountsError::Hash(e.to_string()))
}

impl Users {
    /// No accounts, to be saved at `path`.
    pub fn empty(path: &Path) -> Users {
        Users { path: path.to_owned(), accounts: BTreeMap::new() }
    }

    /// Reads the users file `path`.
    pub fn load(path: &Path) -> Result<Users, AccountsError> {
        let io = |source| AccountsError::Io { path: path.to_owned(), source };
        let size = std::fs::metadata(path).map_err(io)?.len();
        if size > MAX_FILE {
            return Err(AccountsError::TooLarge { path: path.to_owned(), size });
        }
        let text = std::fs::read_to_string(path).map_err(io)?;
        Users::parse(&text, path)
    }

    /// Reads the users file `path`, or no accounts when it does not exist (`user add` to a new
    /// file).
    pub fn load_or_empty(path: &Path) -> Result<Users, AccountsError> {
        match Users::load(path) {
            Err(AccountsError::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
                Ok(Users::empty(path))
            }
            other => other,
        }
    }

    /// Parses the text of a users file; `path` names it in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Users, AccountsError> {
        let invalid = |span: Option<Range<usize>>, message: String| AccountsError::Invalid {
            path: path.to_owned(),
            line: span.map_or(0, |s| line_of(text, s.start)),
            message,
        };
        let file: FileRepr =
            toml::from_str(text).map_err(|e| invalid(e.span(), e.message().trim().to_string()))?;
        let mut accounts = BTreeMap::new();
        for user in file.user {
            let user = user.into_inner();
            let name = user.name.get_ref();
            if !valid_name(name) {
                return Err(invalid(
                    Some(user.name.span()),
                    AccountsError::BadName { name: name.clone() }.to_string(),
                ));
            }
            let role = Role::from_name(user.role.get_ref()).ok_or_else(|| {
                invalid(
                    Some(user.role.span()),
                    AccountsError::BadRole { role: user.role.get_ref().clone() }.to_string(),
                )
            })?;
            let hash = user.hash.get_ref();
            if let Err(e) = argon2::password_hash::phc::PasswordHash::new(hash) {
                return Err(invalid(
                    Some(user.hash.span()),
                    format!("the hash of `{name}` is not an argon2 PHC string: {e}"),
                ));
            }
            if accounts.contains_key(name) {
                return Err(invalid(Some(user.name.span()), format!("user `{name}` is named twice")));
            }
            accounts.insert(name.clone(), Account { role, hash: hash.clone() });
        }
        Ok(Users { path: path.to_owned(), accounts })
    }

    /// The file these accounts come from or go to.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The role of `name` if `password` is its password; `None` for an unknown name or a wrong
    /// password (both take the time of one argon2 check).
    pub fn verify(&self, name: &str, password: &str) -> Option<Role> {
        if password.len() > MAX_PASSWORD {
            return None;
        }
        match self.accounts.get(name) {
            Some(account) => {
                argon2().verify_password(password.as_bytes(), account.hash.as_str()).ok()?;
                Some(account.role)
            }
            None => {
                let _ = argon2().verify_password(password.as_bytes(), decoy_hash());
                None
            }
        }
    }

    /// The role of `name`, if it has an account.
    pub fn role(&self, name: &str) -> Option<Role> {
        self.accounts.get(name).map(|a| a.role)
    }

    /// Every account's name and role, by name.
    pub fn list(&self) -> impl Iterator<Item = (&str, Role)> {
        self.accounts.iter().map(|(n, a)| (n.as_str(), a.role))
    }

    /// How many accounts there are.
    pub fn len(&self) -> usize {
        self.accounts.len()
    }

    /// Whether there are no accounts.
    pub fn is_empty(&self) -> bool {
        self.accounts.is_empty()
    }

    /// Adds the account `name` with `role`, storing the argon2 hash of `password`.
    pub fn add(&mut self, name: &str, password: &str, role: Role) -> Result<(), AccountsError> {
        if !valid_name(name) {
            return Err(AccountsError::BadName { name: name.to_string() });
        }
        if self.accounts.contains_key(name) {
            return Err(AccountsError::Exists { path: self.path.clone(), name: name.to_string() });
        }
        let hash = hash_password(password)?;
        self.accounts.insert(name.to_string(), Account { role, hash });
        Ok(())
    }

    /// Removes the account `name`.
    pub fn remove(&mut self, name: &str) -> Result<(), AccountsError> {
        self.accounts
            .remove(name)
            .map(drop)
            .ok_or_else(|| AccountsError::NoSuchUser { path: self.path.clone(), name: name.to_string() })
    }

    /// The users file's text.
    pub fn to_toml(&self) -> String {
        let mut out = String::from("# dnet-master users file: written by `dnet-master user add`.\n");
        for (name, account) in &self.accounts {
            out.push_str("\n[[user]]\n");
            out.push_str(&format!("name = {}\n", toml::Value::String(name.clone())));
            out.push_str(&format!("role = \"{}\"\n", account.role.name()));
            out.push_str(&format!("hash = {}\n", toml::Value::String(account.hash.clone())));
        }
        out
    }

    /// Writes the users file (to a temporary file beside it, then renamed over it; mode 0600 on
    /// Unix).
    pub fn save(&self) -> Result<(), AccountsError> {
        let io = |source| AccountsError::Io { path: self.path.clone(), source };
        let mut tmp = self.path.clone().into_os_string();
        tmp.push(".tmp");
        let tmp = PathBuf::from(tmp);
        let mut options = std::fs::OpenOptions::new();
        options.write(true).create(true).truncate(true);
        #[cfg(unix)]
        {
            use std::os::unix::fs::OpenOptionsExt;
            options.mode(0o600);
        }
        let write = || -> std::io::Result<()> {
            use std::io::Write;
            let mut file = options.open(&tmp)?;
            #[cfg(unix)]
            {
                use std::os::unix::fs::PermissionsExt;
                file.set_permissions(std::fs::Permissions::from_mode(0o600))?;
            }
            file.write_all(self.to_toml().as_bytes())?;
            file.sync_all()?;
            std::fs::rename(&tmp, &self.path)
        };
        write().map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            io(e)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case::viewer(Role::Viewer, [true, false, false])]
    #[case::operator(Role::Operator, [true, true, false])]
    #[case::engineer(Role::Engineer, [true, true, true])]
    fn roles_may(#[case] role: Role, #[case] may: [bool; 3]) {
        let got = [Action::View, Action::Operate, Action::Engineer].map(|a| role.may(a));
        assert_eq!(got, may);
        assert_eq!(role.name().parse::<Role>().ok(), Some(role));
    }

    #[test]
    fn add_save_load_verify() {
        let dir = std::env::temp_dir().join(format!("dnet-accounts-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("users.toml");
        let mut users = Users::load_or_empty(&path).unwrap();
        users.add("alice", "s3cret", Role::Operator).unwrap();
        users.add("bob", "pw", Role::Viewer).unwrap();
        assert!(matches!(users.add("alice", "x", Role::Viewer), Err(AccountsError::Exists { .. })));
        users.save().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(!text.contains("s3cret"), "the password is stored: {text}");
        assert!(text.contains("$argon2id$"), "{text}");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
            assert_eq!(mode, 0o600);
        }
        let mut users = Users::load(&path).unwrap();
        assert_eq!(users.verify("alice", "s3cret"), Some(Role::Operator));
        assert_eq!(users.verify("alice", "s3creT"), None);
        assert_eq!(users.verify("bob", "pw"), Some(Role::Viewer));
        assert_eq!(users.verify("carol", "pw"), None);
        assert_eq!(users.list().collect::<Vec<_>>(), [("alice", Role::Operator), ("bob", Role::Viewer)]);
        users.remove("bob").unwrap();
        assert!(matches!(users.remove("bob"), Err(AccountsError::NoSuchUser { .. })));
        users.save().unwrap();
        assert_eq!(Users::load(&path).unwrap().len(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[rstest]
    #[case::password_empty("")]
    #[case::password_too_long(&"x".repeat(MAX_PASSWORD + 1))]
    fn bad_passwords_are_refused(#[case] password: &str) {
        let mut users = Users::empty(Path::new("u.toml"));
        assert!(matches!(users.add("a", password, Role::Viewer), Err(AccountsError::BadPassword)));
    }

    const HASH: &str =
        "$argon2id$v=19$m=19456,t=2,p=1$c29tZXNhbHRzb21lc2FsdA$Rm9vYmFyRm9vYmFyRm9vYmFyRm9vYmFyRm9vYmFyRm8";

    #[rstest]
    #[case::unknown_key(
        "[[user]]\nname = \"a\"\nrole = \"viewer\"\nhash = \"H\"\nshell = \"sh\"\n",
        5,
        "unknown field `shell`"
    )]
    #[case::unknown_top_key("users = 1\n", 1, "unknown field `users`")]
    #[case::missing_hash("[[user]]\nname = \"a\"\nrole = \"viewer\"\n", 1, "missing field `hash`")]
    #[case::bad_role("[[user]]\nname = \"a\"\nrole = \"admin\"\nhash = \"H\"\n", 3, "unknown role `admin`")]
    #[case::bad_name("[[user]]\nname = \"a b\"\nrole = \"viewer\"\nhash = \"H\"\n", 2, "bad user name `a b`")]
    #[case::bad_hash(
        "[[user]]\nname = \"a\"\nrole = \"viewer\"\nhash = \"plain\"\n",
        4,
        "not an argon2 PHC string"
    )]
    #[case::twice("[[user]]\nname = \"a\"\nrole = \"viewer\"\nhash = \"H\"\n[[user]]\nname = \"a\"\nrole = \"viewer\"\nhash = \"H\"\n", 6, "named twice")]
    fn bad_files_name_file_and_line(#[case] text: &str, #[case] line: usize, #[case] message: &str) {
        let text = text.replace("\"H\"", &format!("\"{HASH}\""));
        let err = Users::parse(&text, Path::new("users.toml")).unwrap_err();
        let shown = err.to_string();
        assert!(shown.starts_with(&format!("users file users.toml, line {line}: ")), "{shown}");
        assert!(shown.contains(message), "{shown}");
    }

    #[test]
    fn names() {
        assert!(valid_name("a.b_c-9"));
        assert!(!valid_name(""));
        assert!(!valid_name(&"a".repeat(MAX_NAME + 1)));
        assert!(!valid_name("a/b"));
    }
}
