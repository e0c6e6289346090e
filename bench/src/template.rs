//! `{{name}}` substitution for the report templates under `bench/templates/`.

use anyhow::{bail, Result};

/// Replaces every `{{name}}` of `template` by the value of `name` in `values`; an unknown
/// name or an unclosed `{{` is an error.
pub fn render(template: &str, values: &[(&str, String)]) -> Result<String> {
    let mut out = String::with_capacity(template.len() * 2);
    let mut rest = template;
    while let Some(i) = rest.find("{{") {
        out.push_str(&rest[..i]);
        let Some(j) = rest[i..].find("}}") else {
            bail!(
                "template: unclosed '{{{{' at {:?}",
                &rest[i..rest.len().min(i + 30)]
            );
        };
        let name = rest[i + 2..i + j].trim();
        match values.iter().find(|(k, _)| *k == name) {
            Some((_, v)) => out.push_str(v),
            None => bail!("template: no value for {{{{{name}}}}}"),
        }
        rest = &rest[i + j + 2..];
    }
    out.push_str(rest);
    Ok(out)
}

/// The text of section `name` of a template made of sections, each introduced by a line
/// `<!-- name -->` and running to the next such line; surrounding whitespace is trimmed.
pub fn section<'a>(template: &'a str, name: &str) -> Result<&'a str> {
    let marker = format!("<!-- {name} -->");
    let Some(i) = template.find(&marker) else {
        bail!("template: no section {name:?}");
    };
    let body = &template[i + marker.len()..];
    let end = body.find("\n<!-- ").unwrap_or(body.len());
    Ok(body[..end].trim())
}

/// [`render`] of section `name` (see [`section`]).
pub fn render_section(template: &str, name: &str, values: &[(&str, String)]) -> Result<String> {
    render(section(template, name)?, values)
}

#[cfg(test)]
mod tests {
    use super::{render, section};

    #[test]
    fn finds_sections() {
        let t = "<!-- a -->\nfirst {{x}}\n\n<!-- b -->\nsecond\n";
        assert_eq!(section(t, "a").unwrap(), "first {{x}}");
        assert_eq!(section(t, "b").unwrap(), "second");
        assert!(section(t, "c").is_err());
    }

    #[test]
    fn substitutes_and_rejects_unknown_names() {
        let v = [("a", "1".to_string()), ("bc", "x y".to_string())];
        assert_eq!(render("{{a}}+{{ bc }}.", &v).unwrap(), "1+x y.");
        assert!(render("{{nope}}", &v).is_err());
        assert!(render("{{a", &v).is_err());
        assert_eq!(render("no braces", &v).unwrap(), "no braces");
    }
}
