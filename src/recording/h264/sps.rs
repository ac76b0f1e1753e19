//! The stream's format from its sequence parameter set (profile, chroma, bit depth).

use super::*;

/// What a sequence parameter set says about the coded pictures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct SpsFormat {
    pub(super) profile_idc: u8,
    /// 0 monochrome, 1 4:2:0, 2 4:2:2, 3 4:4:4.
    pub(super) chroma_format_idc: u32,
    pub(super) bit_depth_luma: u32,
    pub(super) bit_depth_chroma: u32,
}

impl SpsFormat {
    /// Parses the start of an SPS NAL unit (header byte included). None when it is too
    /// short or not an SPS.
    pub(super) fn parse(sps: &[u8]) -> Option<SpsFormat> {
        if sps.len() < 4 || sps[0] & 0x1f != NAL_SPS {
            return None;
        }
        let profile_idc = sps[1];
        let mut f = SpsFormat {
            profile_idc,
            chroma_format_idc: 1,
            bit_depth_luma: 8,
            bit_depth_chroma: 8,
        };
        // The profiles whose SPS codes the chroma format and bit depths (H.264 7.3.2.1.1).
        if matches!(
            profile_idc,
            100 | 110 | 122 | 244 | 44 | 83 | 86 | 118 | 128 | 138 | 139 | 134 | 135
        ) {
            // The RBSP after level_idc, emulation prevention bytes (00 00 03) removed.
            let mut rbsp = Vec::with_capacity(sps.len());
            let mut zeros = 0;
            for &b in &sps[4..] {
                if zeros >= 2 && b == 3 {
                    zeros = 0;
                    continue;
                }
                zeros = if b == 0 { zeros + 1 } else { 0 };
                rbsp.push(b);
            }
            let mut bits = BitReader {
                data: &rbsp,
                pos: 0,
            };
            bits.ue()?; // seq_parameter_set_id
            f.chroma_format_idc = bits.ue()?;
            if f.chroma_format_idc == 3 {
                bits.bit()?; // separate_colour_plane_flag
            }
            // bit_depth_*_minus8: 0..=6 in a valid stream; a damaged one may say anything.
            f.bit_depth_luma = 8u32.checked_add(bits.ue()?)?;
            f.bit_depth_chroma = 8u32.checked_add(bits.ue()?)?;
        }
        Some(f)
    }

    /// OpenH264 decodes 8-bit 4:2:0 only.
    pub(super) fn openh264_decodes(&self) -> bool {
        self.chroma_format_idc == 1 && self.bit_depth_luma == 8 && self.bit_depth_chroma == 8
    }
}

impl std::fmt::Display for SpsFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let chroma = match self.chroma_format_idc {
            0 => "monochrome",
            1 => "4:2:0",
            2 => "4:2:2",
            3 => "4:4:4",
            _ => "unknown chroma",
        };
        write!(
            f,
            "profile {} ({chroma}, {}-bit)",
            self.profile_idc, self.bit_depth_luma
        )
    }
}

/// Big-endian bit reader for Exp-Golomb codes.
pub(super) struct BitReader<'a> {
    pub(super) data: &'a [u8],
    pub(super) pos: usize,
}

impl BitReader<'_> {
    pub(super) fn bit(&mut self) -> Option<u32> {
        let b = self.data.get(self.pos / 8)?;
        let v = (b >> (7 - self.pos % 8)) & 1;
        self.pos += 1;
        Some(u32::from(v))
    }
    /// Unsigned Exp-Golomb code ue(v).
    pub(super) fn ue(&mut self) -> Option<u32> {
        let mut zeros = 0;
        while self.bit()? == 0 {
            zeros += 1;
            if zeros > 31 {
                return None;
            }
        }
        let mut v = 1u64;
        for _ in 0..zeros {
            v = (v << 1) | u64::from(self.bit()?);
        }
        u32::try_from(v - 1).ok()
    }
}
