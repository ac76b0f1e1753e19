//! The avatar in 3-D: an orbit camera ([`super::orbit`]), and an [`AvatarRenderer`]
//! thread that renders the mesh with Lambert shading into its own colour + depth
//! textures (egui's pass has no depth buffer), whose picture an [`AvatarCallback`] draws
//! as a textured quad.
//!
//! The render is the most expensive thing on the screen for a software rasteriser (tens
//! of thousands of triangles). Done inside a screen frame it would delay that frame's
//! present, and with it the camera views and measurements of the snapshot it shows; so
//! it runs on its own thread, submitted right after a frame has been presented, in the
//! gap before the next one, and the next frame shows it.
//!
//! Conventions: the mesh is in the station frame (metres, +Y up, +Z toward the front
//! camera, +X the subject's left). The orbit camera turns about +Y around `target`;
//! yaw 0 looks from +Z (the front camera's side), yaw +90 degrees from +X (the side
//! camera's side). Texture sizes are physical pixels.

use super::orbit::NEAR_M;
pub use super::orbit::{OrbitCamera, ViewPreset};
#[cfg(test)]
use super::orbit::{DISTANCE_RANGE_M, PITCH_LIMIT_RAD};
use super::stats::FrameClock;
use crate::mesh::TriMesh;
use eframe::egui_wgpu::{self, wgpu};
use glam::Vec3;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Base colour of the avatar (linear RGB); the screenshot test looks for its hue.
pub const AVATAR_RGB: [f32; 3] = [0.20, 0.55, 0.85];
/// Background of the avatar view (sRGB 0..1): the window's clear colour, so that only
/// the part of the view around the body needs to be drawn each frame.
pub const AVATAR_BACKGROUND: [f64; 3] = [
    super::SCREEN_BACKGROUND_RGB[0] as f64 / 255.0,
    super::SCREEN_BACKGROUND_RGB[1] as f64 / 255.0,
    super::SCREEN_BACKGROUND_RGB[2] as f64 / 255.0,
];

const SHADER: &str = r#"
struct Uniforms {
    view_proj: mat4x4<f32>,
    eye: vec4<f32>,
    colour: vec4<f32>,
};
@group(0) @binding(0) var<uniform> u: Uniforms;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) world: vec3<f32>,
};

@vertex
fn vs_mesh(@location(0) pos: vec3<f32>, @location(1) normal: vec3<f32>) -> VsOut {
    var o: VsOut;
    o.clip = u.view_proj * vec4<f32>(pos, 1.0);
    o.normal = normal;
    o.world = pos;
    return o;
}

@fragment
fn fs_mesh(i: VsOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    var n = normalize(i.normal);
    if (!front) { n = -n; }
    // Lambert: a key light from the viewer's upper left and a dim fill from above.
    let to_eye = normalize(u.eye.xyz - i.world);
    let key = normalize(to_eye + vec3<f32>(-0.3, 0.5, 0.0));
    let lambert = max(dot(n, key), 0.0) * 0.8 + max(n.y, 0.0) * 0.15 + 0.12;
    let linear = u.colour.rgb * lambert;
    // Gamma 2 (a square root) instead of pow(x, 1/2.2): the same look, and far cheaper
    // per pixel on a software rasteriser.
    return vec4<f32>(sqrt(max(linear, vec3<f32>(0.0))), 1.0);
}

struct BlitOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

@vertex
fn vs_blit(@builtin(vertex_index) k: u32) -> BlitOut {
    // One triangle covering the viewport.
    let x = f32((k << 1u) & 2u);
    let y = f32(k & 2u);
    var o: BlitOut;
    o.clip = vec4<f32>(x * 2.0 - 1.0, 1.0 - y * 2.0, 0.0, 1.0);
    o.uv = vec2<f32>(x, y);
    return o;
}

@group(0) @binding(0) var tex: texture_2d<f32>;
@group(0) @binding(1) var samp: sampler;

@fragment
fn fs_blit(i: BlitOut) -> @location(0) vec4<f32> {
    // The picture has the view's size: one texel per pixel, no filtering needed.
    let d = vec2<i32>(textureDimensions(tex));
    let p = clamp(vec2<i32>(i.uv * vec2<f32>(d)), vec2<i32>(0, 0), d - vec2<i32>(1, 1));
    return textureLoad(tex, p, 0);
}
"#;

const COLOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Bytes of the uniform block: mat4 + 2 vec4.
const UNIFORM_BYTES: u64 = 64 + 16 + 16;

/// GPU state of the avatar view, owned by the [`AvatarRenderer`] thread.
struct AvatarResources {
    /// Back faces culled: for closed meshes, whose winding is made outward at upload.
    /// Half the triangles never reach the rasteriser (on a software renderer the
    /// per-triangle cost dominates the avatar's render).
    mesh_pipeline: wgpu::RenderPipeline,
    /// Both faces drawn: for meshes that enclose no volume (no outside to tell).
    mesh_pipeline_two_sided: wgpu::RenderPipeline,
    blit_pipeline: wgpu::RenderPipeline,
    uniform_buffer: wgpu::Buffer,
    uniform_bind_group: wgpu::BindGroup,
    blit_layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    target: Option<Target>,
    mesh: Option<GpuMesh>,
    /// Scratch for vertex data (position + normal interleaved).
    vertex_scratch: Vec<f32>,
    index_scratch: Vec<u32>,
}

struct Target {
    size: [u32; 2],
    colour_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    blit_bind_group: wgpu::BindGroup,
}

struct GpuMesh {
    generation: u64,
    /// The mesh is closed enough to have an outside, and the triangles were sent
    /// wound counter-clockwise seen from it: back faces can be culled.
    cull_back: bool,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
    vertex_capacity: u64,
    index_capacity: u64,
}

/// The uniform block shared by the mesh and its shading: its layout, buffer and bind
/// group.
fn uniforms(device: &wgpu::Device) -> (wgpu::BindGroupLayout, wgpu::Buffer, wgpu::BindGroup) {
    let uniform_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("avatar_uniforms"),
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: wgpu::BufferSize::new(UNIFORM_BYTES),
            },
            count: None,
        }],
    });
    let uniform_buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("avatar_uniforms"),
        size: UNIFORM_BYTES,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let uniform_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("avatar_uniforms"),
        layout: &uniform_layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: uniform_buffer.as_entire_binding(),
        }],
    });
    (uniform_layout, uniform_buffer, uniform_bind_group)
}

/// The pipelines that draw the avatar's triangles into the offscreen target with depth:
/// back faces culled, and two-sided.
fn mesh_pipelines(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    uniform_layout: &wgpu::BindGroupLayout,
) -> (wgpu::RenderPipeline, wgpu::RenderPipeline) {
    let mesh_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("avatar_mesh"),
        bind_group_layouts: &[Some(uniform_layout)],
        immediate_size: 0,
    });
    let mesh_pipeline_for = |cull_mode| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("avatar_mesh"),
            layout: Some(&mesh_layout),
            vertex: wgpu::VertexState {
                module,
                entry_point: Some("vs_mesh"),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: 6 * 4,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3],
                })],
                compilation_options: wgpu::PipelineCompilationOptions::default(),
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                front_face: wgpu::FrontFace::Ccw,
                cull_mode,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: wgpu::StencilState::default(),
                bias: wgpu::DepthBiasState::default(),
            }),
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module,
                entry_point: Some("fs_mesh"),
                targets: &[Some(wgpu::ColorTargetState {
                    format: COLOUR_FORMAT,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
                compilation_options: wgpu::PipelineCompilationOptions::default(),
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    let mesh_pipeline = mesh_pipeline_for(Some(wgpu::Face::Back));
    let mesh_pipeline_two_sided = mesh_pipeline_for(None);
    (mesh_pipeline, mesh_pipeline_two_sided)
}

/// The pipeline that copies the offscreen picture into egui's pass, with the layout of
/// its texture and sampler.
fn blit_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    target_format: wgpu::TextureFormat,
) -> (wgpu::BindGroupLayout, wgpu::RenderPipeline) {
    let blit_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("avatar_blit"),
        entries: &[
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: true },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            },
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                count: None,
            },
        ],
    });
    let blit_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("avatar_blit"),
        bind_group_layouts: &[Some(&blit_layout)],
        immediate_size: 0,
    });
    let blit_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("avatar_blit"),
        layout: Some(&blit_pipeline_layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_blit"),
            buffers: &[],
            compilation_options: wgpu::PipelineCompilationOptions::default(),
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: None,
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some("fs_blit"),
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
    (blit_layout, blit_pipeline)
}

impl AvatarResources {
    /// Creates the pipelines; `target_format` is the format of egui's pass.
    fn new(device: &wgpu::Device, target_format: wgpu::TextureFormat) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("avatar"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let (uniform_layout, uniform_buffer, uniform_bind_group) = uniforms(device);
        let (mesh_pipeline, mesh_pipeline_two_sided) =
            mesh_pipelines(device, &module, &uniform_layout);
        let (blit_layout, blit_pipeline) = blit_pipeline(device, &module, target_format);
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("avatar_blit"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        AvatarResources {
            mesh_pipeline,
            mesh_pipeline_two_sided,
            blit_pipeline,
            uniform_buffer,
            uniform_bind_group,
            blit_layout,
            sampler,
            target: None,
            mesh: None,
            vertex_scratch: Vec::new(),
            index_scratch: Vec::new(),
        }
    }

    fn ensure_target(&mut self, device: &wgpu::Device, size: [u32; 2]) {
        if self.target.as_ref().is_some_and(|t| t.size == size) {
            return;
        }
        let extent = wgpu::Extent3d {
            width: size[0],
            height: size[1],
            depth_or_array_layers: 1,
        };
        let make = |format, usage, label| {
            device
                .create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: extent,
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage,
                    view_formats: &[],
                })
                .create_view(&wgpu::TextureViewDescriptor::default())
        };
        let colour_view = make(
            COLOUR_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            "avatar_colour",
        );
        let depth_view = make(
            DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
            "avatar_depth",
        );
        let blit_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("avatar_blit"),
            layout: &self.blit_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&colour_view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(&self.sampler),
                },
            ],
        });
        self.target = Some(Target {
            size,
            colour_view,
            depth_view,
            blit_bind_group,
        });
    }

    fn upload_mesh(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        mesh: &TriMesh,
        generation: u64,
    ) {
        if self
            .mesh
            .as_ref()
            .is_some_and(|m| m.generation == generation)
        {
            return;
        }
        let normals = mesh.vertex_normals();
        self.vertex_scratch.clear();
        for (p, n) in mesh.positions.iter().zip(&normals) {
            self.vertex_scratch.extend_from_slice(&[
                p.x as f32, p.y as f32, p.z as f32, n.x as f32, n.y as f32, n.z as f32,
            ]);
        }
        let nv = mesh.positions.len() as u32;
        let orientation = winding_orientation(mesh);
        self.index_scratch.clear();
        // Triangles with out-of-range indices are skipped rather than sent to the GPU.
        for t in &mesh.triangles {
            if t.iter().all(|&i| i < nv) {
                if orientation == Some(false) {
                    // Inward winding: sent reversed, so that the outside is the front.
                    self.index_scratch.extend_from_slice(&[t[0], t[2], t[1]]);
                } else {
                    self.index_scratch.extend_from_slice(t);
                }
            }
        }
        let vbytes: &[u8] = bytemuck::cast_slice(&self.vertex_scratch);
        let ibytes: &[u8] = bytemuck::cast_slice(&self.index_scratch);
        let need_v = (vbytes.len() as u64).max(4).next_multiple_of(4);
        let need_i = (ibytes.len() as u64).max(4).next_multiple_of(4);
        let reuse = self
            .mesh
            .as_ref()
            .is_some_and(|m| m.vertex_capacity >= need_v && m.index_capacity >= need_i);
        if !reuse {
            let buffer = |size, usage, label| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size,
                    usage: usage | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            };
            // Grow with headroom so a live-deforming avatar does not reallocate.
            let (cv, ci) = (need_v * 3 / 2, need_i * 3 / 2);
            self.mesh = Some(GpuMesh {
                generation,
                cull_back: false,
                vertices: buffer(
                    cv.next_multiple_of(4),
                    wgpu::BufferUsages::VERTEX,
                    "avatar_vertices",
                ),
                indices: buffer(
                    ci.next_multiple_of(4),
                    wgpu::BufferUsages::INDEX,
                    "avatar_indices",
                ),
                index_count: 0,
                vertex_capacity: cv.next_multiple_of(4),
                index_capacity: ci.next_multiple_of(4),
            });
        }
        if let Some(m) = self.mesh.as_mut() {
            if !vbytes.is_empty() {
                queue.write_buffer(&m.vertices, 0, vbytes);
            }
            if !ibytes.is_empty() {
                queue.write_buffer(&m.indices, 0, ibytes);
            }
            m.index_count = self.index_scratch.len() as u32;
            m.generation = generation;
            m.cull_back = orientation.is_some();
        }
    }
}

/// Whether `mesh`'s triangles are wound counter-clockwise seen from outside (`true`)
/// or from inside (`false`), from the sign of the volume they enclose; `None` when the
/// mesh has no outside to tell: it encloses next to nothing, or it is open (the volume
/// "enclosed" by an open mesh depends on the point it is measured from, that of a
/// closed one does not; a body with small holes is close enough to closed). Then both
/// faces must be drawn.
pub fn winding_orientation(mesh: &TriMesh) -> Option<bool> {
    let bounds = mesh.bounds()?;
    // Six times the signed volume, seen from the box's centre and from its corner.
    let (centre, corner) = (bounds.center(), bounds.min);
    let (mut from_centre, mut from_corner) = (0.0f64, 0.0f64);
    for t in &mesh.triangles {
        let at = |k: usize| mesh.positions.get(t[k] as usize).copied();
        if let (Some(p), Some(q), Some(r)) = (at(0), at(1), at(2)) {
            from_centre += (p - centre).dot((q - centre).cross(r - centre));
            from_corner += (p - corner).dot((q - corner).cross(r - corner));
        }
    }
    let size = bounds.size();
    let box_volume = size.x * size.y * size.z;
    // A body fills a good part of its bounding box; a thousandth is next to nothing.
    let enclosed = box_volume > 0.0 && (from_centre / 6.0).abs() >= 1e-3 * box_volume;
    let closed = (from_centre - from_corner).abs() <= CLOSED_VOLUME_TOLERANCE * from_centre.abs();
    (enclosed && closed).then_some(from_centre > 0.0)
}

/// Relative difference of the volumes seen from two points up to which a mesh counts as
/// closed (small holes such as a body's eyes or mouth change it by far less).
const CLOSED_VOLUME_TOLERANCE: f64 = 0.02;

/// What the avatar view should show: a mesh (or none) from a camera at a size.
#[derive(Clone)]
pub struct AvatarJob {
    pub mesh: Option<Arc<TriMesh>>,
    /// Changes whenever `mesh` changes (so the upload happens once per new mesh).
    pub generation: u64,
    pub camera: OrbitCamera,
    /// Size of the picture, physical pixels (the view's size on screen).
    pub size_px: [u32; 2],
    /// Where the body can appear in the view, normalised device coordinates
    /// (x0, y0, x1, y1; +y up), from [`ndc_bounds`]; only that part is drawn each frame
    /// (the rest is the window's clear colour). `None`: the whole view.
    pub body_ndc: Option<[f32; 4]>,
}

/// Identifies what a picture shows: an unchanged view is not rendered again.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AvatarKey {
    generation: Option<u64>,
    camera: [f32; 6],
    size_px: [u32; 2],
}

impl AvatarJob {
    pub fn key(&self) -> AvatarKey {
        let c = &self.camera;
        AvatarKey {
            generation: self.mesh.as_ref().map(|_| self.generation),
            camera: [
                c.yaw,
                c.pitch,
                c.distance_m,
                c.target.x,
                c.target.y,
                c.target.z,
            ],
            size_px: self.size_px,
        }
    }
}

/// A rendered picture of the avatar view, ready to be drawn.
pub struct AvatarPicture {
    pub key: AvatarKey,
    /// A mesh was drawn (otherwise the picture is the empty view).
    pub has_mesh: bool,
    /// See [`AvatarJob::body_ndc`].
    pub body_ndc: Option<[f32; 4]>,
    bind_group: wgpu::BindGroup,
    pipeline: wgpu::RenderPipeline,
}

/// Draws an [`AvatarPicture`] into the avatar view's rectangle.
pub struct AvatarCallback {
    pub picture: Arc<AvatarPicture>,
}

/// Pixels added around the body's projected box before drawing it.
const BODY_BOX_MARGIN_PX: f32 = 3.0;

/// The projected box of `mesh`'s bounding box seen by `camera` at `aspect`, normalised
/// device coordinates (x0, y0, x1, y1), clamped to the view; `None` when a corner is
/// behind the camera (then the whole view is drawn).
pub fn ndc_bounds(mesh: &TriMesh, camera: &OrbitCamera, aspect: f32) -> Option<[f32; 4]> {
    let b = mesh.bounds()?;
    let vp = camera.view_proj(aspect);
    let mut out = [f32::MAX, f32::MAX, f32::MIN, f32::MIN];
    for k in 0..8 {
        let c = glam::DVec3::new(
            if k & 1 == 0 { b.min.x } else { b.max.x },
            if k & 2 == 0 { b.min.y } else { b.max.y },
            if k & 4 == 0 { b.min.z } else { b.max.z },
        );
        let p = vp * Vec3::new(c.x as f32, c.y as f32, c.z as f32).extend(1.0);
        if p.w <= NEAR_M * 0.5 {
            return None;
        }
        let (x, y) = (p.x / p.w, p.y / p.w);
        out = [out[0].min(x), out[1].min(y), out[2].max(x), out[3].max(y)];
    }
    let c = |v: f32| v.clamp(-1.0, 1.0);
    Some([c(out[0]), c(out[1]), c(out[2]), c(out[3])])
}

impl AvatarResources {
    /// Renders `job` into the colour texture (submitted to `queue`); the picture to
    /// draw it with.
    fn render(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        job: &AvatarJob,
    ) -> Option<Arc<AvatarPicture>> {
        let size = job.size_px.map(|v| v.clamp(1, 8192));
        self.ensure_target(device, size);
        if let Some(mesh) = &job.mesh {
            self.upload_mesh(device, queue, mesh, job.generation);
        }
        let vp = job.camera.view_proj(size[0] as f32 / size[1] as f32);
        let eye = job.camera.eye();
        let mut uniforms = [0f32; 24];
        uniforms[..16].copy_from_slice(&vp.to_cols_array());
        uniforms[16..20].copy_from_slice(&[eye.x, eye.y, eye.z, 1.0]);
        uniforms[20..24].copy_from_slice(&[AVATAR_RGB[0], AVATAR_RGB[1], AVATAR_RGB[2], 1.0]);
        queue.write_buffer(&self.uniform_buffer, 0, bytemuck::cast_slice(&uniforms));
        let target = self.target.as_ref()?;
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("avatar"),
        });
        let mut drawn = false;
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("avatar"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target.colour_view,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: AVATAR_BACKGROUND[0],
                            g: AVATAR_BACKGROUND[1],
                            b: AVATAR_BACKGROUND[2],
                            a: 1.0,
                        }),
                        store: wgpu::StoreOp::Store,
                    },
                    depth_slice: None,
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &target.depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                occlusion_query_set: None,
                timestamp_writes: None,
                multiview_mask: None,
            });
            if let (Some(m), true) = (self.mesh.as_ref(), job.mesh.is_some()) {
                if m.index_count > 0 {
                    pass.set_pipeline(if m.cull_back {
                        &self.mesh_pipeline
                    } else {
                        &self.mesh_pipeline_two_sided
                    });
                    pass.set_bind_group(0, &self.uniform_bind_group, &[]);
                    pass.set_vertex_buffer(0, m.vertices.slice(..));
                    pass.set_index_buffer(m.indices.slice(..), wgpu::IndexFormat::Uint32);
                    pass.draw_indexed(0..m.index_count, 0, 0..1);
                    drawn = true;
                }
            }
        }
        queue.submit([encoder.finish()]);
        super::trace::ev(
            "avatar_render",
            self.mesh.as_ref().map_or(0, |m| m.index_count as u64),
        );
        Some(Arc::new(AvatarPicture {
            key: job.key(),
            has_mesh: drawn,
            body_ndc: job.body_ndc,
            bind_group: target.blit_bind_group.clone(),
            pipeline: self.blit_pipeline.clone(),
        }))
    }
}

/// Longest wait of the render thread for the present of the frame that asked for a
/// render (a window that presents nothing, hidden or closing, must not stall it).
const PRESENT_WAIT_MAX: Duration = Duration::from_millis(50);
/// How often the render thread looks whether that frame has been presented.
const PRESENT_POLL: Duration = Duration::from_millis(1);

#[derive(Default)]
struct RendererShared {
    /// The newest render asked for, with the number of frames presented when it was.
    job: Mutex<Option<(AvatarJob, u64)>>,
    wake: Condvar,
    stop: AtomicBool,
    picture: Mutex<Option<Arc<AvatarPicture>>>,
}

/// Renders the avatar on its own thread, between the screen's frames (see the module
/// docs). Dropping it stops the thread.
pub struct AvatarRenderer {
    shared: Arc<RendererShared>,
    thread: Option<JoinHandle<()>>,
    /// What was asked for last (asking again for the same is a no-op).
    asked: Option<AvatarKey>,
}

impl AvatarRenderer {
    /// Starts the thread on egui's device and queue; `clock` tells it when a frame has
    /// been presented, `notify` is called after each new picture (to paint it).
    pub fn start(
        device: wgpu::Device,
        queue: wgpu::Queue,
        target_format: wgpu::TextureFormat,
        clock: FrameClock,
        notify: Box<dyn Fn() + Send>,
    ) -> std::io::Result<Self> {
        let shared = Arc::new(RendererShared::default());
        let s = shared.clone();
        let thread = std::thread::Builder::new()
            .name("avatar".into())
            .spawn(move || {
                let mut gpu = AvatarResources::new(&device, target_format);
                while let Some(job) = next_job(&s, &clock) {
                    if let Some(p) = gpu.render(&device, &queue, &job) {
                        if let Ok(mut slot) = s.picture.lock() {
                            *slot = Some(p);
                        }
                        notify();
                    }
                }
            })?;
        Ok(AvatarRenderer {
            shared,
            thread: Some(thread),
            asked: None,
        })
    }

    /// Asks for `job` to be rendered once the frame being drawn now has been presented
    /// (`presented`: the frames presented so far); a newer request replaces one not
    /// yet started. Asking again for what was asked last does nothing.
    pub fn request(&mut self, job: AvatarJob, presented: u64) {
        let key = job.key();
        if self.asked == Some(key) {
            return;
        }
        self.asked = Some(key);
        if let Ok(mut j) = self.shared.job.lock() {
            *j = Some((job, presented));
        }
        self.shared.wake.notify_all();
    }

    /// The newest finished picture.
    pub fn picture(&self) -> Option<Arc<AvatarPicture>> {
        self.shared.picture.lock().ok().and_then(|p| p.clone())
    }
}

/// The next job for the render thread, once the frame that asked for it has been
/// presented (or [`PRESENT_WAIT_MAX`] has passed); `None` when the thread must stop.
fn next_job(s: &RendererShared, clock: &FrameClock) -> Option<AvatarJob> {
    let (job, after) = {
        let mut j = s.job.lock().ok()?;
        loop {
            if s.stop.load(Ordering::Relaxed) {
                return None;
            }
            if let Some(taken) = j.take() {
                break taken;
            }
            j = s.wake.wait(j).ok()?;
        }
    };
    let since = Instant::now();
    loop {
        if s.stop.load(Ordering::Relaxed) {
            return None;
        }
        if clock.frames() > after || since.elapsed() >= PRESENT_WAIT_MAX {
            // A newer request that came meanwhile is rendered instead (now: while the
            // view is dragged every frame asks for one, and waiting for each would
            // never render any).
            let newer = s.job.lock().ok().and_then(|mut j| j.take());
            return Some(newer.map_or(job, |(newer, _)| newer));
        }
        std::thread::sleep(PRESENT_POLL);
    }
}

impl Drop for AvatarRenderer {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        self.shared.wake.notify_all();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl egui_wgpu::CallbackTrait for AvatarCallback {
    fn paint(
        &self,
        info: egui::PaintCallbackInfo,
        render_pass: &mut wgpu::RenderPass<'static>,
        _resources: &egui_wgpu::CallbackResources,
    ) {
        let pic = &self.picture;
        // Nothing to show: the window's clear colour is the view's background.
        if !pic.has_mesh {
            return;
        }
        if let Some([x0, y0, x1, y1]) = pic.body_ndc {
            let vp = info.viewport_in_pixels();
            let clip = info.clip_rect_in_pixels();
            let to_px_x = |x: f32| vp.left_px as f32 + (x + 1.0) * 0.5 * vp.width_px as f32;
            let to_px_y = |y: f32| vp.top_px as f32 + (1.0 - y) * 0.5 * vp.height_px as f32;
            let left = (to_px_x(x0) - BODY_BOX_MARGIN_PX).max(clip.left_px as f32);
            let right =
                (to_px_x(x1) + BODY_BOX_MARGIN_PX).min((clip.left_px + clip.width_px) as f32);
            let top = (to_px_y(y1) - BODY_BOX_MARGIN_PX).max(clip.top_px as f32);
            let bottom =
                (to_px_y(y0) + BODY_BOX_MARGIN_PX).min((clip.top_px + clip.height_px) as f32);
            if right <= left || bottom <= top {
                return;
            }
            let (l, t) = (left.floor().max(0.0) as u32, top.floor().max(0.0) as u32);
            let (r, b) = (right.ceil() as u32, bottom.ceil() as u32);
            let [sw, sh] = info.screen_size_px;
            let (r, b) = (r.min(sw), b.min(sh));
            if r <= l || b <= t {
                return;
            }
            render_pass.set_scissor_rect(l, t, r - l, b - t);
        }
        render_pass.set_pipeline(&pic.pipeline);
        render_pass.set_bind_group(0, &pic.bind_group, &[]);
        render_pass.draw(0..3, 0..1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_look_from_the_named_side() {
        let mut c = OrbitCamera::default();
        c.preset(ViewPreset::Front);
        assert!(c.eye().z > c.target.z + 1.0 && c.eye().x.abs() < 1e-4);
        c.preset(ViewPreset::Side);
        assert!(c.eye().x > c.target.x + 1.0 && (c.eye().z - c.target.z).abs() < 1e-4);
        c.preset(ViewPreset::ThreeQuarter);
        assert!(c.eye().x > 0.5 && c.eye().z > 0.5);
    }

    #[test]
    fn fit_keeps_the_body_inside_the_view() {
        let size = Vec3::new(0.9, 1.75, 0.3);
        for aspect in [0.4f32, 0.75, 1.5] {
            for preset in [
                ViewPreset::Front,
                ViewPreset::Side,
                ViewPreset::ThreeQuarter,
            ] {
                let mut c = OrbitCamera {
                    target: Vec3::new(0.0, 0.875, 0.0),
                    ..Default::default()
                };
                c.preset(preset);
                c.fit(size, aspect);
                let vp = c.view_proj(aspect);
                for sx in [-0.45f32, 0.45] {
                    for sy in [0.0f32, 1.75] {
                        for sz in [-0.15f32, 0.15] {
                            let p = vp * Vec3::new(sx, sy, sz).extend(1.0);
                            assert!(
                                (p.x / p.w).abs() <= 1.0 && (p.y / p.w).abs() <= 1.0,
                                "{aspect} {preset:?}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// A closed box (12 triangles, wound counter-clockwise seen from outside).
    fn unit_box() -> TriMesh {
        let positions: Vec<glam::DVec3> = (0..8)
            .map(|k| glam::DVec3::new((k & 1) as f64, ((k >> 1) & 1) as f64, ((k >> 2) & 1) as f64))
            .collect();
        let triangles = vec![
            [0, 2, 1],
            [1, 2, 3], // z = 0, seen from -z
            [4, 5, 6],
            [5, 7, 6], // z = 1
            [0, 1, 4],
            [1, 5, 4], // y = 0
            [2, 6, 3],
            [3, 6, 7], // y = 1
            [0, 4, 2],
            [2, 4, 6], // x = 0
            [1, 3, 5],
            [3, 7, 5], // x = 1
        ];
        TriMesh::new(positions, triangles)
    }

    #[test]
    fn winding_is_told_from_the_enclosed_volume() {
        let mut m = unit_box();
        assert_eq!(winding_orientation(&m), Some(true));
        for t in &mut m.triangles {
            t.swap(1, 2);
        }
        assert_eq!(winding_orientation(&m), Some(false));
        // Without one side the box is open: no outside to tell.
        m.triangles.drain(0..2);
        assert_eq!(winding_orientation(&m), None);
        // A flat sheet encloses nothing.
        m.triangles.truncate(2);
        assert_eq!(winding_orientation(&m), None);
    }

    #[test]
    fn target_projects_to_the_centre_and_drag_is_clamped() {
        let mut c = OrbitCamera::default();
        let p = c.view_proj(0.75) * c.target.extend(1.0);
        assert!((p.x / p.w).abs() < 1e-5 && (p.y / p.w).abs() < 1e-5);
        assert!(p.z / p.w > 0.0 && p.z / p.w < 1.0);
        c.drag(0.0, 1e6, 1e6);
        assert!(c.pitch <= PITCH_LIMIT_RAD && c.distance_m >= DISTANCE_RANGE_M.0);
    }
}
