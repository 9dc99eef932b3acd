//! Who a session is: anonymous, or an account of the console's users file (`ui --users`) proved by
//! a UserName identity token. The accounts and roles are the console's
//! ([`dnet_scanner::accounts`]): anonymous sessions and viewers browse, read and subscribe;
//! operators and engineers may also call the methods ([`Action::Operate`]).
//!
//! UserName tokens are offered only on the encrypted endpoint (Basic256Sha256, Sign & Encrypt):
//! on the endpoint without security a password would cross the network readable, so that endpoint
//! takes anonymous sessions only.

use async_trait::async_trait;
use dnet_scanner::accounts::{Action, Role, Users};
use opcua::crypto::SecurityPolicy;
use opcua::server::authenticator::{user_pass_security_policy_id, AuthManager, Password, UserToken};
use opcua::server::ServerEndpoint;
use opcua::types::{Error, StatusCode, UAString, UserTokenPolicy, UserTokenType};
use std::sync::Arc;

/// The policy id of the anonymous token: the one async-opcua checks when a session is activated.
const POLICY_ANONYMOUS: &str = "anonymous";

/// The server's [`AuthManager`] over the console's accounts.
pub struct Accounts {
    users: Option<Arc<Users>>,
}

impl Accounts {
    /// Accounts from `users` (`None`: no users file, every session is anonymous).
    #[must_use]
    pub fn new(users: Option<Arc<Users>>) -> Accounts {
        Accounts { users }
    }

    /// The role of the session's user: `None` for anonymous (or a name no longer in the file).
    #[must_use]
    pub fn role(&self, token: &UserToken) -> Option<Role> {
        if token.is_anonymous() {
            return None;
        }
        self.users.as_ref()?.role(&token.0)
    }

    /// Whether the session's user may operate the plant (call Open, Close, SetOutput); the
    /// refusal in words otherwise.
    pub fn may_operate(&self, token: &UserToken) -> Result<(), String> {
        match self.role(token) {
            Some(role) if role.may(Action::Operate) => Ok(()),
            Some(role) => Err(format!("role {role} may not operate")),
            None if self.users.is_none() => {
                Err("no accounts (ui --users): methods need an operator account".into())
            }
            None => Err("anonymous sessions may only browse and read".into()),
        }
    }

    /// `true` when UserName tokens are taken on `endpoint`: accounts are loaded and the endpoint
    /// encrypts.
    fn takes_usernames(&self, endpoint: &ServerEndpoint) -> bool {
        self.users.is_some() && endpoint.security_policy() != SecurityPolicy::None
    }
}

#[async_trait]
impl AuthManager for Accounts {
    async fn authenticate_anonymous_token(&self, _endpoint: &ServerEndpoint) -> Result<(), Error> {
        Ok(())
    }

    async fn authenticate_username_identity_token(
        &self,
        endpoint: &ServerEndpoint,
        username: &str,
        password: &Password,
    ) -> Result<UserToken, Error> {
        let refused =
            |why: &str| Error::new(StatusCode::BadIdentityTokenRejected, format!("user {username:?}: {why}"));
        if !self.takes_usernames(endpoint) {
            return Err(refused("user names are taken only on the Basic256Sha256 endpoint"));
        }
        let users = self.users.clone().ok_or_else(|| refused("no accounts"))?;
        let (name, password) = (username.to_string(), password.get().to_string());
        // argon2 takes tens of ms of CPU: off the runtime's worker threads.
        let role = tokio::task::spawn_blocking(move || users.verify(&name, &password))
            .await
            .map_err(|_| refused("the check did not finish"))?;
        match role {
            Some(_) => Ok(UserToken(username.to_string())),
            None => Err(refused("unknown user or wrong password")),
        }
    }

    fn user_token_policies(&self, endpoint: &ServerEndpoint) -> Vec<UserTokenPolicy> {
        let mut policies = vec![UserTokenPolicy {
            policy_id: UAString::from(POLICY_ANONYMOUS),
            token_type: UserTokenType::Anonymous,
            issued_token_type: UAString::null(),
            issuer_endpoint_url: UAString::null(),
            security_policy_uri: UAString::null(),
        }];
        if self.takes_usernames(endpoint) {
            policies.push(UserTokenPolicy {
                // The id async-opcua checks: it names how the password is encrypted.
                policy_id: user_pass_security_policy_id(endpoint),
                token_type: UserTokenType::UserName,
                issued_token_type: UAString::null(),
                issuer_endpoint_url: UAString::null(),
                // Null: the endpoint's own policy encrypts the password.
                security_policy_uri: UAString::null(),
            });
        }
        policies
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn accounts() -> Accounts {
        let mut users = Users::empty(Path::new("users.toml"));
        users.add("op", "op pw", Role::Operator).unwrap();
        users.add("en", "en pw", Role::Engineer).unwrap();
        users.add("vi", "vi pw", Role::Viewer).unwrap();
        Accounts::new(Some(Arc::new(users)))
    }

    fn token(name: &str) -> UserToken {
        UserToken(name.to_string())
    }

    #[test]
    fn operators_and_engineers_may_operate() {
        let a = accounts();
        assert_eq!(a.may_operate(&token("op")), Ok(()));
        assert_eq!(a.may_operate(&token("en")), Ok(()));
    }

    #[test]
    fn viewers_anonymous_and_unknown_names_may_not() {
        let a = accounts();
        assert_eq!(a.may_operate(&token("vi")), Err("role viewer may not operate".into()));
        let anonymous = token(opcua::server::ANONYMOUS_USER_TOKEN_ID);
        assert!(a.may_operate(&anonymous).unwrap_err().contains("anonymous"));
        assert!(a.may_operate(&token("gone")).is_err());
    }

    #[test]
    fn without_accounts_nobody_may_operate() {
        let a = Accounts::new(None);
        assert!(a.may_operate(&token("op")).unwrap_err().contains("--users"));
    }
}
