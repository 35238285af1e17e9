//! A minimal CSV table (RFC 4180 quoting).

use std::fmt::Write;

/// A table with a header row; every row has the header's width.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CsvTable {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl CsvTable {
    pub fn new<S: Into<String>>(header: impl IntoIterator<Item = S>) -> CsvTable {
        CsvTable {
            header: header.into_iter().map(Into::into).collect(),
            rows: Vec::new(),
        }
    }

    pub fn header(&self) -> &[String] {
        &self.header
    }

    pub fn rows(&self) -> &[Vec<String>] {
        &self.rows
    }

    /// Appends a row.
    ///
    /// # Panics
    /// If the row's width differs from the header's (a programming error).
    pub fn push<S: Into<String>>(&mut self, row: impl IntoIterator<Item = S>) {
        let row: Vec<String> = row.into_iter().map(Into::into).collect();
        assert_eq!(
            row.len(),
            self.header.len(),
            "CSV row width must match the header"
        );
        self.rows.push(row);
    }

    /// The CSV text, one line per row, `\n` line ends.
    pub fn to_csv(&self) -> String {
        let mut out = String::new();
        for line in std::iter::once(&self.header).chain(&self.rows) {
            for (i, field) in line.iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                if field.contains([',', '"', '\n', '\r']) {
                    let _ = write!(out, "\"{}\"", field.replace('"', "\"\""));
                } else {
                    out.push_str(field);
                }
            }
            out.push('\n');
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quotes_fields_that_need_it() {
        let mut t = CsvTable::new(["a", "b"]);
        t.push(["1", "x,y"]);
        t.push(["say \"hi\"", ""]);
        assert_eq!(t.to_csv(), "a,b\n1,\"x,y\"\n\"say \"\"hi\"\"\",\n");
    }
}
