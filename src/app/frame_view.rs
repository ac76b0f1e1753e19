//! Camera frames drawn by a wgpu paint callback: one texel per displayed texel, read
//! with a texel load, no blending. On a software rasteriser this costs a fraction of an
//! egui image (which samples an sRGB texture and blends every pixel); the overlays are
//! painted by egui on top.
//!
//! The frame is box-filtered on the `process` thread to about the view's size (see
//! [`super::display`]) and uploaded once per new frame (`generation`); the texture is
//! reused while the size stays. Texture values are the frame's sRGB bytes, written as
//! they are to the (non-sRGB) window surface, as egui's own colours are.

use super::display::DisplayImage;
use eframe::egui_wgpu::{self, wgpu};
use std::sync::Arc;

const SHADER: &str = r#"
struct Out {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

@vertex
fn vs_main(@builtin(vertex_index) k: u32) -> Out {
    // One triangle covering the viewport (the view's rectangle).
    let x = f32((k << 1u) & 2u);
    let y = f32(k & 2u);
    var o: Out;
    o.clip = vec4<f32>(x * 2.0 - 1.0, 1.0 - y * 2.0, 0.0, 1.0);
    o.uv = vec2<f32>(x, y);
    return o;
}

@group(0) @binding(0) var frame: texture_2d<f32>;

@fragment
fn fs_main(i: Out) -> @location(0) vec4<f32> {
    let d = vec2<i32>(textureDimensions(frame));
    let p = clamp(vec2<i32>(i.uv * vec2<f32>(d)), vec2<i32>(0, 0), d - vec2<i32>(1, 1));
    return vec4<f32>(textureLoad(frame, p, 0).rgb, 1.0);
}
"#;

/// Number of camera views (front, side).
pub const VIEWS: usize = 2;

/// GPU state of the camera views, kept in egui-wgpu's callback resources.
pub struct FrameViewResources {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    views: [Option<ViewTexture>; VIEWS],
}

struct ViewTexture {
    size: [u32; 2],
    texture: wgpu::Texture,
    bind_group: wgpu::BindGroup,
    generation: u64,
}

impl FrameViewResources {
    /// Creates the pipeline; `target_format` is the format of egui's pass.
    pub fn new(device: &wgpu::Device, target_format: wgpu::TextureFormat) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("camera_view"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("camera_view"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            }],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("camera_view"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("camera_view"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                buffers: &[],
                compilation_options: wgpu::PipelineCompilationOptions::default(),
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                targets: &[Some(wgpu::ColorTargetState {
                    format: target_format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
                compilation_options: wgpu::PipelineCompilationOptions::default(),
            }),
            multiview_mask: None,
            cache: None,
        });
        FrameViewResources {
            pipeline,
            layout,
            views: [None, None],
        }
    }

    fn upload(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        slot: usize,
        image: &DisplayImage,
        generation: u64,
    ) {
        let size = image.size;
        let pixels = size[0] as usize * size[1] as usize;
        if pixels == 0 || image.rgba.len() != 4 * pixels {
            return;
        }
        let Some(entry) = self.views.get_mut(slot) else {
            return;
        };
        if entry
            .as_ref()
            .is_some_and(|v| v.generation == generation && v.size == size)
        {
            return;
        }
        let extent = wgpu::Extent3d {
            width: size[0],
            height: size[1],
            depth_or_array_layers: 1,
        };
        if entry.as_ref().is_none_or(|v| v.size != size) {
            let texture = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("camera_view"),
                size: extent,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba8Unorm,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            });
            let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("camera_view"),
                layout: &self.layout,
                entries: &[wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&view),
                }],
            });
            *entry = Some(ViewTexture {
                size,
                texture,
                bind_group,
                generation,
            });
        }
        if let Some(v) = entry.as_mut() {
            queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &v.texture,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                &image.rgba,
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(4 * size[0]),
                    rows_per_image: Some(size[1]),
                },
                extent,
            );
            v.generation = generation;
        }
    }
}

/// One camera view to draw this frame.
pub struct FrameViewCallback {
    /// 0 front, 1 side.
    pub slot: usize,
    /// The display image (uploaded when `generation` changes).
    pub image: Arc<DisplayImage>,
    pub generation: u64,
}

impl egui_wgpu::CallbackTrait for FrameViewCallback {
    fn prepare(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        _screen: &egui_wgpu::ScreenDescriptor,
        _encoder: &mut wgpu::CommandEncoder,
        resources: &mut egui_wgpu::CallbackResources,
    ) -> Vec<wgpu::CommandBuffer> {
        if let Some(res) = resources.get_mut::<FrameViewResources>() {
            res.upload(device, queue, self.slot, &self.image, self.generation);
        }
        Vec::new()
    }

    fn paint(
        &self,
        _info: egui::PaintCallbackInfo,
        render_pass: &mut wgpu::RenderPass<'static>,
        resources: &egui_wgpu::CallbackResources,
    ) {
        let Some(res) = resources.get::<FrameViewResources>() else {
            return;
        };
        let Some(Some(v)) = res.views.get(self.slot) else {
            return;
        };
        render_pass.set_pipeline(&res.pipeline);
        render_pass.set_bind_group(0, &v.bind_group, &[]);
        render_pass.draw(0..3, 0..1);
    }
}
