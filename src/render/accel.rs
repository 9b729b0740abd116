//! The device's acceleration structures for ray-query traversal: one bottom level for the world's triangles and one
//! per instanced mesh, compacted, and a top level over them, built from the packed scene the compute BVH is built
//! from, so a hit names the same triangle and instance record in both traversals (traverse.glsl, RAY_QUERY).
use super::gpu_scene::PackedScene;
use crate::constants::FEATURE_MOTION;
use crate::error::Error;
use crate::vk::{Buffer, Context};
use ash::vk;
use gpu_allocator::MemoryLocation;

/// An instance's custom index holds its mesh's first triangle in 24 bits.
const CUSTOM_INDEX_LIMIT: u32 = 1 << 24;

/// Why a packed scene cannot be traced with ray queries on `ctx` (the renderer then keeps the compute BVH and says
/// this), or None when it can.
pub fn unsupported(ctx: &Context, packed: &PackedScene) -> Option<String> {
    if ctx.accel.is_none() {
        return Some("this device has no ray queries".into());
    }
    // Motion in acceleration structures is an NVIDIA extension: moving triangles and instances keep the compute BVH,
    // which interpolates them exactly (a per-segment structure would blur them differently from it).
    let moving_instance = packed.instances.iter().skip(1).any(|r| r.info[3] != 0);
    if packed.features() & FEATURE_MOTION != 0 || moving_instance {
        return Some("the scene moves over the shutter, and ray-query motion blur is vendor-only".into());
    }
    if packed.tri_verts.is_empty() {
        return Some("the scene has no triangles".into());
    }
    let last = packed.meshes.last().map_or(0, |m| m.first);
    if last >= CUSTOM_INDEX_LIMIT
        || (packed.meshes.is_empty() && packed.tri_verts.len() as u64 > CUSTOM_INDEX_LIMIT as u64)
    {
        return Some(format!(
            "its triangles outnumber the {CUSTOM_INDEX_LIMIT} an instance's custom index can start from"
        ));
    }
    None
}

/// The built structures and the buffers holding them; the top level is what BINDING_TLAS binds.
pub struct AccelStructures {
    pub tlas: vk::AccelerationStructureKHR,
    /// Every structure (the bottom levels, then the top) with its buffer; destroyed before the buffers drop.
    structures: Vec<(vk::AccelerationStructureKHR, Buffer)>,
    /// Device bytes of the structures once compacted.
    pub bytes: u64,
    /// Device bytes of the structures had the bottom levels not been compacted.
    pub uncompacted_bytes: u64,
    /// Host and device time of the builds, compaction included.
    pub build_time: std::time::Duration,
    loader: ash::khr::acceleration_structure::Device,
}

impl Drop for AccelStructures {
    fn drop(&mut self) {
        if crate::vk::device_lost() {
            return;
        }
        for (s, _) in &self.structures {
            unsafe { self.loader.destroy_acceleration_structure(*s, None) };
        }
    }
}

/// One bottom level's triangles: a range of the packed ones.
struct Range {
    first: u32,
    count: u32,
}

/// 64 bytes: VkAccelerationStructureInstanceKHR as the device reads it: the 3x4 world-from-object rows, the custom
/// index (24 bits) and mask (8), the binding-table offset (24) and flags (8), the bottom level's device address.
fn instance_words(rows: [[f32; 4]; 3], custom_index: u32, mask: u32, blas: u64) -> [u32; 16] {
    let mut w = [0u32; 16];
    for (r, row) in rows.iter().enumerate() {
        for (c, x) in row.iter().enumerate() {
            w[r * 4 + c] = x.to_bits();
        }
    }
    w[12] = custom_index | mask << 24;
    // Both faces are hit: pathwave decides one- and two-sidedness when shading, as the compute BVH leaves it to.
    w[13] = vk::GeometryInstanceFlagsKHR::TRIANGLE_FACING_CULL_DISABLE.as_raw() << 24;
    w[14] = blas as u32;
    w[15] = (blas >> 32) as u32;
    w
}

/// Buffer usages of the builds' inputs, the structures and the scratch space.
const INPUT_USAGE: vk::BufferUsageFlags = vk::BufferUsageFlags::from_raw(
    vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR.as_raw()
        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS.as_raw(),
);
const STRUCTURE_USAGE: vk::BufferUsageFlags = vk::BufferUsageFlags::from_raw(
    vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR.as_raw()
        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS.as_raw(),
);
const SCRATCH_USAGE: vk::BufferUsageFlags = vk::BufferUsageFlags::from_raw(
    vk::BufferUsageFlags::STORAGE_BUFFER.as_raw() | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS.as_raw(),
);

/// The bottom levels as built, before compaction.
struct Bottom {
    built: Vec<vk::AccelerationStructureKHR>,
    /// Each one's size as built, and as the driver would compact it (0: no answer).
    sizes: Vec<u64>,
    compacted: Vec<u64>,
}

/// Every bottom level's vertices, three a triangle (v0, v0 + e1, v0 + e2, as the compute traversal's arithmetic
/// places them), in one buffer the builds read.
fn vertex_buffer(ctx: &Context, packed: &PackedScene) -> Result<Buffer, Error> {
    let vertices: Vec<[f32; 3]> = packed
        .tri_verts
        .iter()
        .flat_map(|t| {
            let v0 = [t.v0[0], t.v0[1], t.v0[2]];
            let add = |e: [f32; 4]| [v0[0] + e[0], v0[1] + e[1], v0[2] + e[2]];
            [v0, add(t.e1), add(t.e2)]
        })
        .collect();
    Buffer::with_data_usage(ctx, "ray-query vertices", &vertices, INPUT_USAGE)
}

/// A bottom level's one geometry: the range's triangles in the vertex buffer at `vertices`.
fn triangles(packed: &PackedScene, r: &Range, vertices: u64) -> [vk::AccelerationStructureGeometryKHR<'static>; 1] {
    let triangles = vk::AccelerationStructureGeometryTrianglesDataKHR::default()
        .vertex_format(vk::Format::R32G32B32_SFLOAT)
        .vertex_data(vk::DeviceOrHostAddressConstKHR {
            device_address: vertices + r.first as u64 * 36,
        })
        .vertex_stride(12)
        .max_vertex((3 * r.count).max(1) - 1)
        .index_type(vk::IndexType::NONE_KHR);
    // Alpha-tested triangles come back to the shader as candidates; with the rest of their mesh they are tested there
    // once each (an any-hit test twice would draw its stochastic coverage twice).
    let alpha = packed.tri_verts[r.first as usize..(r.first + r.count) as usize]
        .iter()
        .any(|t| t.e1[3] != 0.0);
    let flags = match alpha {
        true => vk::GeometryFlagsKHR::NO_DUPLICATE_ANY_HIT_INVOCATION,
        false => vk::GeometryFlagsKHR::OPAQUE,
    };
    [vk::AccelerationStructureGeometryKHR::default()
        .geometry_type(vk::GeometryTypeKHR::TRIANGLES)
        .geometry(vk::AccelerationStructureGeometryDataKHR { triangles })
        .flags(flags)]
}

impl AccelStructures {
    /// Builds the structures for `packed` (`unsupported` must have said None), refusing by name when they would
    /// take more than `budget` bytes of device memory: the bottom levels (the world's triangles, then each instanced
    /// mesh's), their compacted copies where those fit, and the top level over them.
    pub fn build(ctx: &Context, packed: &PackedScene, budget: u64) -> Result<Self, Error> {
        let start = std::time::Instant::now();
        let mut me = AccelStructures {
            tlas: vk::AccelerationStructureKHR::null(),
            structures: Vec::new(),
            bytes: 0,
            uncompacted_bytes: 0,
            build_time: std::time::Duration::ZERO,
            loader: ctx.accel.clone().expect("unsupported() checks for ray queries"),
        };
        let world = packed
            .instances
            .first()
            .map_or(packed.tri_verts.len() as u32, |h| h.info[2]);
        let mut ranges = vec![Range { first: 0, count: world }];
        ranges.extend(packed.meshes.iter().map(|m| Range {
            first: m.first,
            count: m.count,
        }));
        let vertices = vertex_buffer(ctx, packed)?;
        let bottom = me.build_bottom(ctx, packed, &ranges, &vertices, budget)?;
        // The copies live beside their sources until the top level is built: where both would not fit the budget the
        // structures stay as built.
        let total: u64 = bottom.sizes.iter().sum();
        let smaller = |i: usize| bottom.compacted[i] > 0 && bottom.compacted[i] < bottom.sizes[i];
        let copy_bytes: u64 = (0..bottom.built.len())
            .filter(|&i| smaller(i))
            .map(|i| bottom.compacted[i])
            .sum();
        let compact = total + copy_bytes + vertices.size <= budget;
        let mut blas = Vec::with_capacity(bottom.built.len());
        let mut copies = Vec::new();
        for (i, (&s, &c)) in bottom.built.iter().zip(&bottom.compacted).enumerate() {
            if compact && smaller(i) {
                let small = me.create(
                    ctx,
                    "compacted bottom-level structure",
                    c,
                    vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
                )?;
                copies.push((s, small));
                blas.push(small);
            } else {
                blas.push(s);
            }
        }
        let words = me.instances(packed, &blas, world > 0)?;
        let top_size = me.build_top(ctx, &words, &copies)?;
        // The uncompacted bottom levels are no longer needed once copied.
        let stale: Vec<vk::AccelerationStructureKHR> = copies.iter().map(|c| c.0).collect();
        let loader = me.loader.clone();
        me.structures.retain(|(s, _)| {
            let keep = !stale.contains(s);
            if !keep {
                unsafe { loader.destroy_acceleration_structure(*s, None) };
            }
            keep
        });
        me.bytes = me.structures.iter().map(|(_, b)| b.size).sum();
        me.uncompacted_bytes = total + top_size;
        me.build_time = start.elapsed();
        Ok(me)
    }

    /// Builds a bottom level per range (refused when they and their scratch space would pass `budget`), then asks
    /// each one's compacted size.
    fn build_bottom(
        &mut self,
        ctx: &Context,
        packed: &PackedScene,
        ranges: &[Range],
        vertices: &Buffer,
        budget: u64,
    ) -> Result<Bottom, Error> {
        let scratch_align = scratch_alignment(ctx);
        let vertex_address = vertices.address(ctx);
        let geometries: Vec<_> = ranges.iter().map(|r| triangles(packed, r, vertex_address)).collect();
        let flags = vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE
            | vk::BuildAccelerationStructureFlagsKHR::ALLOW_COMPACTION;
        let mut infos: Vec<vk::AccelerationStructureBuildGeometryInfoKHR> = geometries
            .iter()
            .map(|g| {
                vk::AccelerationStructureBuildGeometryInfoKHR::default()
                    .ty(vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL)
                    .flags(flags)
                    .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
                    .geometries(g)
            })
            .collect();
        let sizes: Vec<vk::AccelerationStructureBuildSizesInfoKHR> = (infos.iter().zip(ranges))
            .map(|(info, r)| self.build_sizes(info, r.count))
            .collect();
        let total: u64 = sizes.iter().map(|s| s.acceleration_structure_size).sum();
        let scratch: u64 = sizes.iter().map(|s| s.build_scratch_size + scratch_align).sum();
        if total + scratch + vertices.size > budget {
            return Err(Error::Settings(format!(
                "the scene's acceleration structures need {} MiB of device memory to build ({} bottom levels), more \
                 than the {} MiB left for them",
                (total + scratch + vertices.size) >> 20,
                ranges.len(),
                budget >> 20
            )));
        }
        let scratch_buffer = scratch_space(ctx, scratch)?;
        let mut scratch_at = scratch_buffer.address(ctx);
        let mut built = Vec::with_capacity(ranges.len());
        for (info, size) in infos.iter_mut().zip(&sizes) {
            let s = self.create(
                ctx,
                "bottom-level structure",
                size.acceleration_structure_size,
                vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
            )?;
            built.push(s);
            let aligned = scratch_at.div_ceil(scratch_align) * scratch_align;
            *info = info
                .dst_acceleration_structure(s)
                .scratch_data(vk::DeviceOrHostAddressKHR {
                    device_address: aligned,
                });
            scratch_at = aligned + size.build_scratch_size;
        }
        let range_infos: Vec<[vk::AccelerationStructureBuildRangeInfoKHR; 1]> = ranges
            .iter()
            .map(|r| [vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(r.count)])
            .collect();
        let range_refs: Vec<&[vk::AccelerationStructureBuildRangeInfoKHR]> =
            range_infos.iter().map(|r| &r[..]).collect();
        let compacted = self.build_and_query(ctx, &infos, &range_refs, &built)?;
        Ok(Bottom {
            built,
            sizes: sizes.iter().map(|s| s.acceleration_structure_size).collect(),
            compacted,
        })
    }

    /// What a build of `info` over `count` primitives takes.
    fn build_sizes(
        &self,
        info: &vk::AccelerationStructureBuildGeometryInfoKHR,
        count: u32,
    ) -> vk::AccelerationStructureBuildSizesInfoKHR<'static> {
        let mut size = vk::AccelerationStructureBuildSizesInfoKHR::default();
        unsafe {
            self.loader.get_acceleration_structure_build_sizes(
                vk::AccelerationStructureBuildTypeKHR::DEVICE,
                info,
                &[count],
                &mut size,
            )
        };
        size
    }

    /// Runs the bottom levels' builds, then reads each one's compacted size.
    fn build_and_query(
        &self,
        ctx: &Context,
        infos: &[vk::AccelerationStructureBuildGeometryInfoKHR],
        ranges: &[&[vk::AccelerationStructureBuildRangeInfoKHR]],
        built: &[vk::AccelerationStructureKHR],
    ) -> Result<Vec<u64>, Error> {
        let queries = unsafe {
            ctx.device.create_query_pool(
                &vk::QueryPoolCreateInfo::default()
                    .query_type(vk::QueryType::ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR)
                    .query_count(built.len() as u32),
                None,
            )
        }?;
        let done = ctx.submit_and_wait(|cmd| unsafe {
            ctx.device.cmd_reset_query_pool(cmd, queries, 0, built.len() as u32);
            self.loader.cmd_build_acceleration_structures(cmd, infos, ranges);
            build_barrier(ctx, cmd, BUILD_THEN_BUILD);
            self.loader.cmd_write_acceleration_structures_properties(
                cmd,
                built,
                vk::QueryType::ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR,
                queries,
                0,
            );
        });
        let mut compacted = vec![0u64; built.len()];
        let read = done.and_then(|()| {
            unsafe {
                ctx.device.get_query_pool_results(
                    queries,
                    0,
                    &mut compacted,
                    vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
                )
            }
            .map_err(Error::from)
        });
        unsafe { ctx.device.destroy_query_pool(queries, None) };
        read.map(|()| compacted)
    }

    /// The top level's instances: instance 0 the world (mask 0 when it has no triangles), instance i the instance
    /// record i, each over its bottom level in `blas` (the world's, then each instanced mesh's).
    fn instances(
        &self,
        packed: &PackedScene,
        blas: &[vk::AccelerationStructureKHR],
        world: bool,
    ) -> Result<Vec<[u32; 16]>, Error> {
        let address = |s: vk::AccelerationStructureKHR| unsafe {
            self.loader.get_acceleration_structure_device_address(
                &vk::AccelerationStructureDeviceAddressInfoKHR::default().acceleration_structure(s),
            )
        };
        let identity = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
        let mask = if world { 0xFF } else { 0 };
        let mut words = vec![instance_words(identity, 0, mask, address(blas[0]))];
        let placed = packed.instances.first().map_or(0, |h| h.info[1] as usize);
        for record in packed.instances.iter().skip(1).take(placed) {
            let mesh = packed.meshes.iter().position(|m| m.root == record.info[0]);
            let mesh = mesh.ok_or_else(|| Error::Vulkan("an instance record names no instanced mesh".into()))?;
            let rows = [record.world0, record.world1, record.world2];
            words.push(instance_words(
                rows,
                packed.meshes[mesh].first,
                0xFF,
                address(blas[1 + mesh]),
            ));
        }
        Ok(words)
    }

    /// Copies the bottom levels into their compacted structures, then builds the top level over `words`' instances;
    /// returns its size.
    fn build_top(
        &mut self,
        ctx: &Context,
        words: &[[u32; 16]],
        copies: &[(vk::AccelerationStructureKHR, vk::AccelerationStructureKHR)],
    ) -> Result<u64, Error> {
        let instance_buffer = Buffer::with_data_usage(ctx, "ray-query instances", words, INPUT_USAGE)?;
        let instances = vk::AccelerationStructureGeometryInstancesDataKHR::default()
            .array_of_pointers(false)
            .data(vk::DeviceOrHostAddressConstKHR {
                device_address: instance_buffer.address(ctx),
            });
        let top_geometry = [vk::AccelerationStructureGeometryKHR::default()
            .geometry_type(vk::GeometryTypeKHR::INSTANCES)
            .geometry(vk::AccelerationStructureGeometryDataKHR { instances })];
        let mut top = vk::AccelerationStructureBuildGeometryInfoKHR::default()
            .ty(vk::AccelerationStructureTypeKHR::TOP_LEVEL)
            .flags(vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE)
            .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
            .geometries(&top_geometry);
        let top_size = self.build_sizes(&top, words.len() as u32);
        let tlas = self.create(
            ctx,
            "top-level structure",
            top_size.acceleration_structure_size,
            vk::AccelerationStructureTypeKHR::TOP_LEVEL,
        )?;
        let scratch_align = scratch_alignment(ctx);
        let top_scratch = scratch_space(ctx, top_size.build_scratch_size + scratch_align)?;
        let aligned = top_scratch.address(ctx).div_ceil(scratch_align) * scratch_align;
        top = top
            .dst_acceleration_structure(tlas)
            .scratch_data(vk::DeviceOrHostAddressKHR {
                device_address: aligned,
            });
        let top_range = [vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(words.len() as u32)];
        ctx.submit_and_wait(|cmd| unsafe {
            for (from, to) in copies {
                self.loader.cmd_copy_acceleration_structure(
                    cmd,
                    &vk::CopyAccelerationStructureInfoKHR::default()
                        .src(*from)
                        .dst(*to)
                        .mode(vk::CopyAccelerationStructureModeKHR::COMPACT),
                );
            }
            build_barrier(ctx, cmd, BUILD_THEN_BUILD);
            self.loader
                .cmd_build_acceleration_structures(cmd, &[top], &[&top_range[..]]);
            // Traversal in every later submission reads what the builds wrote.
            build_barrier(ctx, cmd, BUILD_THEN_TRACE);
        })?;
        self.tlas = tlas;
        Ok(top_size.acceleration_structure_size)
    }

    /// A structure of `size` bytes in a buffer of its own, kept until the structures drop.
    fn create(
        &mut self,
        ctx: &Context,
        name: &str,
        size: u64,
        ty: vk::AccelerationStructureTypeKHR,
    ) -> Result<vk::AccelerationStructureKHR, Error> {
        let buffer = Buffer::new(ctx, name, size, STRUCTURE_USAGE, MemoryLocation::GpuOnly)?;
        let s = unsafe {
            self.loader.create_acceleration_structure(
                &vk::AccelerationStructureCreateInfoKHR::default()
                    .buffer(buffer.raw)
                    .size(size)
                    .ty(ty),
                None,
            )
        }?;
        self.structures.push((s, buffer));
        Ok(s)
    }
}

/// Who waits for the builds and copies before a build_barrier: the stage and the accesses.
type Waiter = (vk::PipelineStageFlags, vk::AccessFlags);

/// Builds, copies and size queries after the barrier.
const BUILD_THEN_BUILD: Waiter = (
    vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
    vk::AccessFlags::from_raw(
        vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR.as_raw()
            | vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR.as_raw(),
    ),
);

/// Traversal in the compute stages of every later submission.
const BUILD_THEN_TRACE: Waiter = (
    vk::PipelineStageFlags::COMPUTE_SHADER,
    vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR,
);

/// Builds and copies before it are complete, and their writes visible, to `waiter`.
fn build_barrier(ctx: &Context, cmd: vk::CommandBuffer, (stage, access): Waiter) {
    let barrier = vk::MemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR)
        .dst_access_mask(access);
    unsafe {
        ctx.device.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
            stage,
            vk::DependencyFlags::empty(),
            &[barrier],
            &[],
            &[],
        )
    };
}

/// Scratch space for builds.
fn scratch_space(ctx: &Context, bytes: u64) -> Result<Buffer, Error> {
    Buffer::new(ctx, "ray-query scratch", bytes, SCRATCH_USAGE, MemoryLocation::GpuOnly)
}

/// The alignment a build's scratch address needs (at least 1).
fn scratch_alignment(ctx: &Context) -> u64 {
    let mut accel = vk::PhysicalDeviceAccelerationStructurePropertiesKHR::default();
    let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut accel);
    unsafe { ctx.instance.get_physical_device_properties2(ctx.physical, &mut p2) };
    (accel.min_acceleration_structure_scratch_offset_alignment as u64).max(1)
}
