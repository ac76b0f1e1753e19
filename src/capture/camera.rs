//! The real cameras (feature `camera`): [`NokhwaCameras`] is the [`DeviceOpener`] of the
//! capture workers ([`super::device`]): it opens a camera through nokhwa/V4L2 at a fixed
//! resolution, frame rate and pixel format (asked with `RequestedFormatType::Closest`);
//! its devices decode MJPEG with zune-jpeg (YUYV by [`super::yuyv_to_rgb`]) and give
//! the driver's capture time. Pairing, reconnecting a failing camera on the
//! [`super::Reconnector`] schedule and the screen's [`SourceError::Disconnected`]
//! meanwhile are the workers' ([`DevicePairSource`]), shared with the fake cameras the
//! tests use.
//!
//! Exposure and white balance: after [`super::CaptureControls::request_lock`] (the
//! backdrop is learnt) each worker switches its camera to manual exposure and fixed
//! white balance with raw V4L2 control ids (nokhwa has no auto/manual switch), and
//! again after every reopen.
//!
//! [`SourceError::Disconnected`]: crate::pipeline::SourceError::Disconnected

use super::device::{
    CameraDevice, DeviceError, DeviceFrame, DeviceOpener, DevicePairSource, Opened,
};
use super::{device_index, yuyv_to_rgb, CaptureConfig, PixelFormat};
use crate::camera::{StationCalibration, View};
use image::RgbImage;
use nokhwa::utils::{
    CameraFormat, CameraIndex, ControlValueSetter, FrameFormat, KnownCameraControl,
    RequestedFormat, RequestedFormatType, Resolution,
};
use std::sync::Arc;

/// V4L2 `V4L2_CID_EXPOSURE_AUTO`: 1 = manual.
const V4L2_CID_EXPOSURE_AUTO: u32 = 0x009a_0901;
const V4L2_EXPOSURE_MANUAL: i64 = 1;
/// V4L2 `V4L2_CID_EXPOSURE_ABSOLUTE`, in units of 100 us.
const V4L2_CID_EXPOSURE_ABSOLUTE: u32 = 0x009a_0902;
/// V4L2 `V4L2_CID_AUTO_WHITE_BALANCE`.
const V4L2_CID_AUTO_WHITE_BALANCE: u32 = 0x0098_090c;

/// Two live cameras as one frame source.
pub type CameraPairSource = DevicePairSource;

impl DevicePairSource {
    /// Starts the workers of the two cameras of `config`. Never fails: a missing camera
    /// is reported by `next_pair` as disconnected and retried.
    pub fn open_cameras(config: CaptureConfig, calibration: Option<StationCalibration>) -> Self {
        let opener = Arc::new(NokhwaCameras {
            config: config.clone(),
        });
        DevicePairSource::open(config, calibration, opener)
    }
}

/// Opens the configured cameras through nokhwa.
pub struct NokhwaCameras {
    config: CaptureConfig,
}

impl DeviceOpener for NokhwaCameras {
    fn open(&self, view: View) -> Result<Opened, String> {
        let device = match view {
            View::Front => &self.config.front,
            View::Side => &self.config.side,
        };
        let index = match device_index(device) {
            Some(i) => CameraIndex::Index(i),
            None => CameraIndex::String(device.clone()),
        };
        let fourcc = match self.config.format {
            PixelFormat::Mjpeg => FrameFormat::MJPEG,
            PixelFormat::Yuyv => FrameFormat::YUYV,
        };
        let want = CameraFormat::new(
            Resolution::new(self.config.width, self.config.height),
            fourcc,
            self.config.fps,
        );
        let requested = RequestedFormat::new::<nokhwa::pixel_format::RgbFormat>(
            RequestedFormatType::Closest(want),
        );
        let mut cam = nokhwa::Camera::new(index, requested).map_err(|e| e.to_string())?;
        cam.open_stream().map_err(|e| e.to_string())?;
        let got = cam.camera_format();
        // Closest may pick another size: say so, the calibration would not fit.
        let warning = (got.resolution() != want.resolution()).then(|| {
            format!(
                "{} camera delivers {}x{} instead of {}x{}",
                view.name(),
                got.resolution().width(),
                got.resolution().height(),
                self.config.width,
                self.config.height
            )
        });
        Ok(Opened {
            device: Box::new(NokhwaDevice {
                cam,
                exposure_100us: self.config.exposure_100us,
                scratch: Vec::new(),
            }),
            warning,
        })
    }
}

/// One open nokhwa camera.
struct NokhwaDevice {
    cam: nokhwa::Camera,
    /// Manual exposure once locked, V4L2 units of 100 us.
    exposure_100us: i64,
    /// Reused RGB buffer of YUYV conversion.
    scratch: Vec<u8>,
}

impl CameraDevice for NokhwaDevice {
    fn frame(&mut self) -> Result<DeviceFrame, DeviceError> {
        // Unplugged or failing: the worker drops the device and reopens on schedule.
        let buf = self
            .cam
            .frame()
            .map_err(|e| DeviceError::Lost(e.to_string()))?;
        // The driver's capture time (V4L2 monotonic, given as wall-clock by nokhwa).
        let captured_unix_s = buf.capture_timestamp().map(|d| d.as_secs_f64());
        let res = buf.resolution();
        let image = decode(
            buf.buffer(),
            buf.source_frame_format(),
            res.width(),
            res.height(),
            &mut self.scratch,
        )
        .map_err(DeviceError::BadFrame)?;
        Ok(DeviceFrame {
            image,
            captured_unix_s,
        })
    }

    fn lock_controls(&mut self) -> Result<(), String> {
        let set = |cam: &mut nokhwa::Camera, id: u32, v: ControlValueSetter| {
            cam.set_camera_control(KnownCameraControl::Other(id as u128), v)
                .map_err(|e| e.to_string())
        };
        set(
            &mut self.cam,
            V4L2_CID_EXPOSURE_AUTO,
            ControlValueSetter::Integer(V4L2_EXPOSURE_MANUAL),
        )?;
        set(
            &mut self.cam,
            V4L2_CID_EXPOSURE_ABSOLUTE,
            ControlValueSetter::Integer(self.exposure_100us),
        )?;
        set(
            &mut self.cam,
            V4L2_CID_AUTO_WHITE_BALANCE,
            ControlValueSetter::Boolean(false),
        )?;
        Ok(())
    }
}

/// Decodes one camera buffer (MJPEG or YUYV) to RGB.
fn decode(
    bytes: &[u8],
    format: FrameFormat,
    w: u32,
    h: u32,
    rgb: &mut Vec<u8>,
) -> Result<RgbImage, String> {
    match format {
        FrameFormat::MJPEG => {
            use zune_jpeg::zune_core::bytestream::ZCursor;
            use zune_jpeg::zune_core::colorspace::ColorSpace;
            use zune_jpeg::zune_core::options::DecoderOptions;
            let opts = DecoderOptions::default().jpeg_set_out_colorspace(ColorSpace::RGB);
            let mut d = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(bytes), opts);
            let pixels = d
                .decode()
                .map_err(|e| format!("corrupt MJPEG frame: {e:?}"))?;
            let info = d.info().ok_or("MJPEG frame without a header")?;
            RgbImage::from_raw(info.width as u32, info.height as u32, pixels)
                .ok_or_else(|| "MJPEG size mismatch".to_string())
        }
        FrameFormat::YUYV => {
            if !yuyv_to_rgb(bytes, w as usize, h as usize, rgb) {
                return Err("short YUYV frame".into());
            }
            RgbImage::from_raw(w, h, std::mem::take(rgb))
                .ok_or_else(|| "YUYV size mismatch".to_string())
        }
        other => Err(format!("unsupported pixel format {other:?}")),
    }
}
