//! An error and its causes as one line, for command-line programs and reports.

/// `error` and each of its sources, joined by `": "`; a source whose text the line already
/// contains (an error that prints its source itself) is not repeated.
pub fn failure_chain(error: &dyn std::error::Error) -> String {
    let mut line = error.to_string();
    let mut source = error.source();
    while let Some(cause) = source {
        let text = cause.to_string();
        if !line.contains(&text) {
            line += ": ";
            line += &text;
        }
        source = cause.source();
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;
    use thiserror::Error;

    #[derive(Debug, Error)]
    #[error("building the thing failed")]
    struct Outer(#[source] Inner);

    #[derive(Debug, Error)]
    #[error("the inner cause")]
    struct Inner;

    #[derive(Debug, Error)]
    #[error("mesh.obj: {0}")]
    struct PrintsItsSource(#[source] Inner);

    #[test]
    fn failure_chain_names_every_cause_after_the_error_once() {
        assert_eq!(
            failure_chain(&Outer(Inner)),
            "building the thing failed: the inner cause"
        );
        assert_eq!(
            failure_chain(&PrintsItsSource(Inner)),
            "mesh.obj: the inner cause"
        );
    }
}
