//! ANSUR II: the real people the `ansur` evaluation population follows.
//!
//! The 2012 Anthropometric Survey of U.S. Army Personnel (public release, public domain)
//! lives in `../shared/data/ansur2/` (see its README): one CSV per sex, 93 tape and
//! caliper measurements per person, lengths in millimetres, `weightkg` in tenths of a
//! kilogram. The male file is Latin-1 (it is read as bytes and converted lossily), the
//! female file UTF-8; the first column is `subjectid` in one and `SubjectId` in the other,
//! so column names are matched without case.
//!
//! Only the columns a synthetic body needs are kept ([`AnsurRecord`]); nothing personal
//! (birthplace, dates, units, age) leaves this module.

use super::rng::SplitMix64;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Default data folder, relative to the current directory.
pub const DEFAULT_DIR: &str = "../shared/data/ansur2";
/// File of the men.
pub const MALE_FILE: &str = "ANSUR_II_MALE_Public.csv";
/// File of the women.
pub const FEMALE_FILE: &str = "ANSUR_II_FEMALE_Public.csv";
/// Stream label of the row draw (see [`AnsurTable::pick`]).
const PICK_STREAM: u64 = 0xA45A;

/// Errors of the ANSUR reader.
#[derive(Debug, thiserror::Error)]
pub enum AnsurError {
    #[error("ANSUR II data not found: tried {tried}; pass --ansur-dir DIR (the folder holding {MALE_FILE} and {FEMALE_FILE})")]
    NotFound { tried: String },
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: no column '{column}' in the header")]
    MissingColumn { path: PathBuf, column: String },
    #[error("{path} line {line}: column '{column}' is not a number: '{value}'")]
    BadValue {
        path: PathBuf,
        line: usize,
        column: String,
        value: String,
    },
    #[error("{path}: no data rows")]
    Empty { path: PathBuf },
}

/// Sex of an ANSUR II subject (which file the row came from).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Sex {
    Female,
    Male,
}

/// The values of one ANSUR II person that a synthetic body uses. Field names are the
/// survey's column names; lengths in millimetres, `weightkg` in tenths of a kilogram
/// (as in the files).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AnsurRecord {
    pub subjectid: u64,
    pub sex: Sex,
    pub stature: f64,
    pub crotchheight: f64,
    pub chestheight: f64,
    pub chestbreadth: f64,
    pub chestdepth: f64,
    pub chestcircumference: f64,
    pub waistheightomphalion: f64,
    pub waistbreadth: f64,
    pub waistdepth: f64,
    pub waistcircumference: f64,
    pub buttockheight: f64,
    pub hipbreadth: f64,
    pub buttockdepth: f64,
    pub buttockcircumference: f64,
    pub thighcircumference: f64,
    pub axillaheight: f64,
    pub acromialheight: f64,
    pub weightkg: f64,
}

/// Numeric columns read into [`AnsurRecord`], in the order of [`AnsurRecord::from_values`].
const COLUMNS: [&str; 19] = [
    "subjectid",
    "stature",
    "crotchheight",
    "chestheight",
    "chestbreadth",
    "chestdepth",
    "chestcircumference",
    "waistheightomphalion",
    "waistbreadth",
    "waistdepth",
    "waistcircumference",
    "buttockheight",
    "hipbreadth",
    "buttockdepth",
    "buttockcircumference",
    "thighcircumference",
    "axillaheight",
    "acromialheight",
    "weightkg",
];

impl AnsurRecord {
    fn from_values(sex: Sex, v: &[f64; COLUMNS.len()]) -> AnsurRecord {
        AnsurRecord {
            subjectid: v[0] as u64,
            sex,
            stature: v[1],
            crotchheight: v[2],
            chestheight: v[3],
            chestbreadth: v[4],
            chestdepth: v[5],
            chestcircumference: v[6],
            waistheightomphalion: v[7],
            waistbreadth: v[8],
            waistdepth: v[9],
            waistcircumference: v[10],
            buttockheight: v[11],
            hipbreadth: v[12],
            buttockdepth: v[13],
            buttockcircumference: v[14],
            thighcircumference: v[15],
            axillaheight: v[16],
            acromialheight: v[17],
            weightkg: v[18],
        }
    }

    /// Body mass index, kg / m^2.
    pub fn bmi(&self) -> f64 {
        let m = self.stature * 1e-3;
        0.1 * self.weightkg / (m * m).max(1e-6)
    }
}

/// Parses one ANSUR II CSV (text already decoded): header, then one person a line.
///
/// # Errors
/// A required column is missing, a value is not a number, or there are no rows.
pub fn parse_csv(text: &str, sex: Sex, path: &Path) -> Result<Vec<AnsurRecord>, AnsurError> {
    let mut lines = text.lines().map(|l| l.trim_end_matches('\r'));
    let header = lines.next().unwrap_or_default();
    let index: HashMap<String, usize> = header
        .split(',')
        .enumerate()
        .map(|(i, name)| (name.trim().to_ascii_lowercase(), i))
        .collect();
    let mut cols = [0usize; COLUMNS.len()];
    for (slot, name) in cols.iter_mut().zip(COLUMNS) {
        *slot = *index.get(name).ok_or_else(|| AnsurError::MissingColumn {
            path: path.to_path_buf(),
            column: name.into(),
        })?;
    }
    let mut out = Vec::new();
    let mut fields: Vec<&str> = Vec::with_capacity(index.len());
    for (k, line) in lines.enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        fields.clear();
        fields.extend(line.split(','));
        let mut v = [0.0; COLUMNS.len()];
        for ((slot, &c), name) in v.iter_mut().zip(&cols).zip(COLUMNS) {
            let raw = fields.get(c).copied().unwrap_or("").trim();
            *slot = raw
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| AnsurError::BadValue {
                    path: path.to_path_buf(),
                    line: k + 2,
                    column: name.into(),
                    value: raw.into(),
                })?;
        }
        out.push(AnsurRecord::from_values(sex, &v));
    }
    if out.is_empty() {
        return Err(AnsurError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(out)
}

/// Reads one file: UTF-8 when it is, otherwise a lossy conversion (the male file's one
/// Latin-1 letter sits in a column this module does not read).
fn read_file(path: &Path, sex: Sex) -> Result<Vec<AnsurRecord>, AnsurError> {
    let bytes = std::fs::read(path).map_err(|source| AnsurError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let text = String::from_utf8_lossy(&bytes);
    parse_csv(&text, sex, path)
}

/// Both files of ANSUR II.
#[derive(Debug, Clone)]
pub struct AnsurTable {
    pub female: Vec<AnsurRecord>,
    pub male: Vec<AnsurRecord>,
}

impl AnsurTable {
    /// Reads both CSV files of `dir`.
    ///
    /// # Errors
    /// A file is missing or malformed.
    pub fn load(dir: &Path) -> Result<AnsurTable, AnsurError> {
        Ok(AnsurTable {
            female: read_file(&dir.join(FEMALE_FILE), Sex::Female)?,
            male: read_file(&dir.join(MALE_FILE), Sex::Male)?,
        })
    }

    /// The rows of one sex.
    pub fn rows(&self, sex: Sex) -> &[AnsurRecord] {
        match sex {
            Sex::Female => &self.female,
            Sex::Male => &self.male,
        }
    }

    /// One person of `sex`, the row drawn from `seed` (deterministic).
    pub fn pick(&self, seed: u64, sex: Sex) -> &AnsurRecord {
        let rows = self.rows(sex);
        let mut rng = SplitMix64::stream(seed, PICK_STREAM);
        // Both files have rows (checked at load), so the modulus is never zero.
        &rows[(rng.next_u64() % rows.len().max(1) as u64) as usize]
    }
}

/// Where the data is: `explicit` if given, else [`DEFAULT_DIR`] relative to the current
/// directory, else the same path beside the crate's source tree (compile-time
/// `CARGO_MANIFEST_DIR`).
///
/// # Errors
/// None of the candidates holds the two files.
pub fn resolve_dir(explicit: Option<&Path>) -> Result<PathBuf, AnsurError> {
    let candidates: Vec<PathBuf> = match explicit {
        Some(d) => vec![d.to_path_buf()],
        None => vec![
            PathBuf::from(DEFAULT_DIR),
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/ansur2"),
        ],
    };
    for d in &candidates {
        if d.join(MALE_FILE).is_file() && d.join(FEMALE_FILE).is_file() {
            return Ok(d.clone());
        }
    }
    Err(AnsurError::NotFound {
        tried: candidates
            .iter()
            .map(|d| d.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table() -> Option<AnsurTable> {
        let dir = resolve_dir(None).ok()?;
        Some(AnsurTable::load(&dir).expect("the ANSUR II files parse"))
    }

    #[test]
    fn both_files_parse_with_every_row() {
        let Some(t) = table() else {
            eprintln!("ANSUR II data not found: skipped");
            return;
        };
        assert_eq!(t.male.len(), 4082);
        assert_eq!(t.female.len(), 1986);
        // Ids present and distinct within a file; values in human ranges.
        for rows in [&t.male, &t.female] {
            let mut ids: Vec<u64> = rows.iter().map(|r| r.subjectid).collect();
            assert!(ids.iter().all(|&i| i > 0));
            ids.sort_unstable();
            ids.dedup();
            assert_eq!(ids.len(), rows.len());
            for r in rows.iter() {
                assert!((1300.0..2100.0).contains(&r.stature), "{r:?}");
                // (The buttock height is below the crotch height for 94 people.)
                assert!(r.crotchheight < r.chestheight && r.buttockheight < r.chestheight);
                assert!((15.0..60.0).contains(&r.bmi()), "{r:?}");
            }
        }
        assert!(t.male.iter().all(|r| r.sex == Sex::Male));
        assert!(t.female.iter().all(|r| r.sex == Sex::Female));
    }

    #[test]
    fn header_case_and_crlf_and_bad_values() {
        let head = COLUMNS.join(",").replace("subjectid", "SubjectId");
        let row: Vec<String> = (0..COLUMNS.len()).map(|i| (i + 1).to_string()).collect();
        let text = format!("{head},Birthplace\r\n{},Lom\u{e9}\r\n", row.join(","));
        let p = Path::new("x.csv");
        let r = parse_csv(&text, Sex::Female, p).expect("parses");
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].subjectid, 1);
        assert_eq!(r[0].weightkg, COLUMNS.len() as f64);
        let bad = format!("{head}\n{}", row.join(",").replacen("2", "x", 1));
        assert!(matches!(
            parse_csv(&bad, Sex::Male, p),
            Err(AnsurError::BadValue { line: 2, .. })
        ));
        let missing = "subjectid,stature\n1,1700\n";
        assert!(matches!(
            parse_csv(missing, Sex::Male, p),
            Err(AnsurError::MissingColumn { .. })
        ));
    }

    #[test]
    fn the_pick_is_deterministic_and_spreads() {
        let Some(t) = table() else { return };
        assert_eq!(
            t.pick(20000, Sex::Male).subjectid,
            t.pick(20000, Sex::Male).subjectid
        );
        let ids: std::collections::BTreeSet<u64> = (0..20)
            .map(|s| t.pick(20000 + s, Sex::Female).subjectid)
            .collect();
        assert!(ids.len() >= 18, "{ids:?}");
    }
}
