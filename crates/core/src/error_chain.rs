//! One line for an error and its causes, as every face shows it (`error: …` of the command
//! line, the service's and the node's logs).
//!
//! An error's message often already holds its cause's (`training: {0}` over the training
//! error, which is also its `source()`), so joining every message of the chain, as
//! `anyhow`'s `{:#}` does, prints that cause twice. [`error_chain`] joins the messages but
//! leaves out a cause whose message the last one shown already contains.

use std::error::Error;

/// `error`'s message and those of its sources (`source()`, outermost first) joined by `": "`,
/// leaving out a cause whose message is empty or contained in the last message shown.
///
/// ```
/// use chronomap_core::error_chain::error_chain;
/// let io = std::io::Error::other("disk full");
/// assert_eq!(error_chain(&io), "disk full");
/// ```
pub fn error_chain(error: &(dyn Error + 'static)) -> String {
    let mut shown = error.to_string();
    let mut last = shown.clone();
    let mut source = error.source();
    while let Some(cause) = source {
        let text = cause.to_string();
        if !text.is_empty() && !last.contains(&text) {
            shown.push_str(": ");
            shown.push_str(&text);
            last = text;
        }
        source = cause.source();
    }
    shown
}

#[cfg(test)]
mod tests {
    use std::fmt;

    use super::*;

    /// An error with a message and an optional cause (`{message}` or `{message}: {cause}`
    /// when `holds_cause`).
    #[derive(Debug)]
    struct Layer {
        message: &'static str,
        holds_cause: bool,
        cause: Option<Box<Layer>>,
    }

    impl fmt::Display for Layer {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str(self.message)?;
            match &self.cause {
                Some(cause) if self.holds_cause => write!(f, ": {cause}"),
                _ => Ok(()),
            }
        }
    }

    impl Error for Layer {
        fn source(&self) -> Option<&(dyn Error + 'static)> {
            self.cause.as_deref().map(|c| c as &(dyn Error + 'static))
        }
    }

    fn layer(message: &'static str, holds_cause: bool, cause: Option<Layer>) -> Layer {
        Layer {
            message,
            holds_cause,
            cause: cause.map(Box::new),
        }
    }

    #[test]
    fn a_cause_the_message_already_holds_is_shown_once() {
        // `#[error("training: {0}")]` over `#[from]`: the cause is both in the message and
        // the source.
        let boost = layer(
            "the first stump has weighted error 0.5 >= 0.5: nothing to boost",
            false,
            None,
        );
        let training = layer("training", true, Some(boost));
        assert_eq!(
            training.to_string(),
            "training: the first stump has weighted error 0.5 >= 0.5: nothing to boost"
        );
        assert_eq!(
            error_chain(&training),
            "training: the first stump has weighted error 0.5 >= 0.5: nothing to boost"
        );
    }

    #[test]
    fn causes_not_in_the_message_are_joined_in_order() {
        let io = layer("No such file or directory (os error 2)", false, None);
        let read = layer("cannot read door.txt", false, Some(io));
        let fit = layer("fitting fremen:2", false, Some(read));
        assert_eq!(
            error_chain(&fit),
            "fitting fremen:2: cannot read door.txt: No such file or directory (os error 2)"
        );
        // A cause held by a message that was itself left out is still compared with the
        // last message shown.
        let root = layer("disk full", false, None);
        let middle = layer("cannot write m.cmm", true, Some(root));
        let outer = layer("saving: cannot write m.cmm: disk full", false, Some(middle));
        assert_eq!(error_chain(&outer), "saving: cannot write m.cmm: disk full");
    }

    #[test]
    fn empty_messages_are_left_out() {
        let empty = layer("", false, None);
        let outer = layer("stopped", false, Some(empty));
        assert_eq!(error_chain(&outer), "stopped");
    }
}
