//! `rootfuse filters`: every registered filter with its parameters.
use rootfuse_attitude::registry::FilterKind;

/// Prints the registry.
pub fn print() {
    for &kind in FilterKind::ALL {
        out!("{}: {}", kind.name(), kind.description());
        for p in kind.params() {
            out!(
                "    {:<14} default {:<8} [{}, {}] {:<10} {}",
                p.name,
                p.default,
                p.min,
                p.max,
                p.unit,
                p.doc.replace('\n', " ")
            );
        }
    }
    out!("\nOverride with --param key=value; --dof 6|9 sets `dof` where a filter has one.");
}
