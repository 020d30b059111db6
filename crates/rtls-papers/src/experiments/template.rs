//! Report prose lives in markdown templates (`crates/rtls-papers/templates/<experiment>.md`),
//! not in string literals; the code computes the numbers and chooses between alternative
//! sentences, the templates hold the words.
//!
//! # Format
//! A template file is a sequence of sections. A line `<!-- name -->` (a lowercase name of
//! letters, digits and `-`) starts the section `name`; everything before the first marker is a
//! comment for the reader. A section is one paragraph: its non-blank lines, trimmed and joined
//! by single spaces (markdown's own soft line break), so the file can be wrapped freely. A
//! placeholder `{key}` (lowercase letters, digits and `_`) is replaced by the value given for
//! `key`; the code formats every number (decimals, sign) before handing it over, so a template
//! holds no formatting logic. A sentence that only some runs need is a section of its own,
//! rendered by the code and passed on as a value.
//!
//! This is deliberately the smallest substitution that does the job (no loops, conditionals or
//! filters as in a templating engine): the rendered notes are byte for byte what the string
//! literals gave, and a missing or unused key is a bug that debug builds (all tests) report.

use std::fmt::Display;

/// One markdown template file of named sections.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Template {
    /// The file's name, for messages (e.g. `wsn-ekf.md`).
    file: &'static str,
    /// The file's text.
    text: &'static str,
}

impl Template {
    /// The template `file` with text `text` (from `include_str!`).
    pub(crate) const fn new(file: &'static str, text: &'static str) -> Self {
        Self { file, text }
    }

    /// The sections' names in file order.
    #[cfg(test)]
    fn section_names(&self) -> Vec<&'static str> {
        self.text.lines().filter_map(marker).collect()
    }

    /// Section `name` as one paragraph: its non-blank lines trimmed and joined by single
    /// spaces; `None` if the file has no such section.
    fn section(&self, name: &str) -> Option<String> {
        let mut lines = self.text.lines();
        lines.find(|line| marker(line) == Some(name))?;
        let paragraph: Vec<&str> = lines
            .take_while(|line| marker(line).is_none())
            .map(str::trim)
            .filter(|line| !line.is_empty())
            .collect();
        Some(paragraph.join(" "))
    }

    /// Section `name` with every `{key}` replaced by the value given for `key`.
    ///
    /// A section the file lacks renders empty, a placeholder without a value stays as it is,
    /// and a value without a placeholder is ignored: each is a bug, and debug builds panic on
    /// it so that the tests, which render every report, catch it.
    pub(crate) fn render(&self, name: &str, values: &[(&str, &dyn Display)]) -> String {
        let Some(section) = self.section(name) else {
            debug_assert!(false, "{}: no section `{name}`", self.file);
            return String::new();
        };
        let mut out = String::with_capacity(section.len() + 16 * values.len());
        let mut used = vec![false; values.len()];
        let mut rest = section.as_str();
        while let Some(open) = rest.find('{') {
            out.push_str(&rest[..open]);
            let after = &rest[open + 1..];
            let key = after.find('}').map(|close| &after[..close]).filter(|key| is_key(key));
            match key {
                Some(key) => {
                    match values.iter().position(|(k, _)| *k == key) {
                        Some(i) => {
                            used[i] = true;
                            out.push_str(&values[i].1.to_string());
                        }
                        None => {
                            debug_assert!(false, "{}: section `{name}`: no value for {{{key}}}", self.file);
                            out.push_str(&rest[open..open + key.len() + 2]);
                        }
                    }
                    rest = &after[key.len() + 1..];
                }
                None => {
                    out.push('{');
                    rest = after;
                }
            }
        }
        out.push_str(rest);
        debug_assert!(
            used.iter().all(|u| *u),
            "{}: section `{name}`: values without a placeholder: {:?}",
            self.file,
            values
                .iter()
                .zip(&used)
                .filter(|(_, u)| !**u)
                .map(|((k, _), _)| *k)
                .collect::<Vec<_>>()
        );
        out
    }
}

/// The section name of a marker line `<!-- name -->`, if `line` is one.
fn marker(line: &str) -> Option<&str> {
    let name = line.strip_prefix("<!-- ")?.strip_suffix(" -->")?;
    let valid = !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-');
    valid.then_some(name)
}

/// Whether `key` is a placeholder name: lowercase letters, digits and `_`.
fn is_key(key: &str) -> bool {
    !key.is_empty()
        && key
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
}

/// Renders a section of a [`Template`] with named values:
/// `render!(NOTES, "setup", runs = options.runs, rmse_m = fmt(rmse, 3))` replaces `{runs}`
/// and `{rmse_m}` in section `setup` by the values' `Display`.
macro_rules! render {
    ($template:expr, $section:expr $(, $key:ident = $value:expr)* $(,)?) => {
        $template.render($section, &[$((stringify!($key), &$value as &dyn ::std::fmt::Display)),*])
    };
}
pub(crate) use render;

/// Every experiment's report prose.
pub(crate) mod files {
    use super::Template;

    /// Seed 000 (`mekf`).
    pub(crate) const MEKF: Template = Template::new("mekf.md", include_str!("../../templates/mekf.md"));
    /// Seed 001 (`ukf-uwb`).
    pub(crate) const UKF_UWB: Template = Template::new("ukf-uwb.md", include_str!("../../templates/ukf-uwb.md"));
    /// Seed 002 (`lwknn`).
    pub(crate) const LWKNN: Template = Template::new("lwknn.md", include_str!("../../templates/lwknn.md"));
    /// Seed 003 (`wsn-ekf`).
    pub(crate) const WSN_EKF: Template = Template::new("wsn-ekf.md", include_str!("../../templates/wsn-ekf.md"));
    /// Seed 004 (`vdkf`).
    pub(crate) const VDKF: Template = Template::new("vdkf.md", include_str!("../../templates/vdkf.md"));

    /// All five.
    #[cfg(test)]
    pub(crate) const ALL: [Template; 5] = [MEKF, UKF_UWB, LWKNN, WSN_EKF, VDKF];
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: Template = Template::new(
        "test.md",
        "A comment for the reader.\n\n<!-- one -->\n**One.** {a} and\n  {b_2} m; {not a key} {}\n\n<!-- two -->\nno placeholders\n",
    );

    #[test]
    fn sections_join_their_lines_and_fill_placeholders() {
        assert_eq!(T.section_names(), ["one", "two"]);
        assert_eq!(
            render!(T, "one", a = 1, b_2 = format!("{:.2}", 0.5)),
            "**One.** 1 and 0.50 m; {not a key} {}"
        );
        assert_eq!(render!(T, "two"), "no placeholders");
    }

    #[test]
    #[should_panic(expected = "no value for {b_2}")]
    fn a_missing_value_is_a_bug() {
        let _ = render!(T, "one", a = 1);
    }

    #[test]
    #[should_panic(expected = "values without a placeholder")]
    fn an_unused_value_is_a_bug() {
        let _ = render!(T, "two", a = 1);
    }

    #[test]
    #[should_panic(expected = "no section `three`")]
    fn a_missing_section_is_a_bug() {
        let _ = render!(T, "three");
    }

    #[test]
    fn every_section_is_rendered_by_its_experiment() {
        let sources = [
            (files::MEKF, include_str!("mekf/notes.rs")),
            (files::UKF_UWB, include_str!("ukf_uwb/notes.rs")),
            (files::LWKNN, include_str!("lwknn/mod.rs")),
            (files::WSN_EKF, include_str!("wsn_ekf/notes.rs")),
            (files::VDKF, include_str!("vdkf/mod.rs")),
        ];
        for (template, source) in sources {
            for name in template.section_names() {
                assert!(
                    source.contains(&format!("\"{name}\"")),
                    "{}: section `{name}` is never rendered",
                    template.file
                );
            }
        }
    }

    #[test]
    fn every_template_has_unique_well_formed_sections() {
        for template in files::ALL {
            let names = template.section_names();
            assert!(!names.is_empty(), "{}", template.file);
            let mut sorted = names.clone();
            sorted.sort_unstable();
            sorted.dedup();
            assert_eq!(sorted.len(), names.len(), "{}: duplicate sections", template.file);
            // a one-word comment line that is not a valid marker is a typo
            for line in template.text.lines() {
                let inner = line.strip_prefix("<!-- ").and_then(|l| l.strip_suffix(" -->"));
                if inner.is_some_and(|w| !w.contains(char::is_whitespace)) {
                    assert!(marker(line).is_some(), "{}: malformed marker {line}", template.file);
                }
            }
            for name in names {
                let text = template.section(name).unwrap();
                assert!(!text.is_empty(), "{}: empty section {name}", template.file);
                assert!(!text.contains("  "), "{}: double space in {name}", template.file);
            }
        }
    }
}
