//! A problem with what the user asked for (a flag, a file, a combination of options), with a
//! hint on what to do instead. Commands exit with 1 on it (bad input), not 2 (a bug); the CLI
//! prints the hint under the error.

/// A problem with what the user asked for, with a hint on what to do instead.
#[derive(Debug)]
pub struct UserError {
    pub message: String,
    pub hint: Option<String>,
}

impl UserError {
    pub fn new(message: impl Into<String>, hint: impl Into<String>) -> UserError {
        UserError {
            message: message.into(),
            hint: Some(hint.into()),
        }
    }
}

impl std::fmt::Display for UserError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for UserError {}
