// Constants shared by Rust and GLSL: build.rs turns this file into `shared_constants.glsl`.
// Only `pub const NAME: u32 = value;` lines are exported, so keep every shared value in that form.

/// Invocations per workgroup of every 1D wavefront stage.
pub const WORKGROUP_SIZE: u32 = 64;

/// Descriptor bindings of the one set every stage shares (set 0).
pub const BINDING_NODES: u32 = 0;
pub const BINDING_TRI_VERTS: u32 = 1;
pub const BINDING_TRI_SHADING: u32 = 2;
pub const BINDING_MATERIALS: u32 = 3;
pub const BINDING_LIGHTS: u32 = 4;
pub const BINDING_PATHS: u32 = 5;
pub const BINDING_QUEUES: u32 = 6;
pub const BINDING_COUNTERS: u32 = 7;
pub const BINDING_FILM: u32 = 8;
pub const BINDING_PROBE: u32 = 9;
pub const BINDING_ENERGY: u32 = 10;
pub const BINDING_ENV: u32 = 11;
pub const BINDING_PUNCTUAL: u32 = 12;
pub const BINDING_TEXTURES: u32 = 13;
pub const BINDING_TEXELS: u32 = 14;
pub const BINDING_TRI_TEXCOORDS: u32 = 15;
pub const BINDING_TRI_TANGENTS: u32 = 16;
pub const BINDING_TRI_COLORS: u32 = 17;
/// The tone map's output: packed 8-bit display pixels (tonemap.comp).
pub const BINDING_TONEMAP_OUT: u32 = 18;
/// Motion over the shutter (FEATURE_MOTION): `MotionKey` records, the camera's keys and then every triangle's after
/// its first; a stand-in where the scene does not move.
pub const BINDING_MOTION: u32 = 19;
/// Instances of meshes kept in object space (FEATURE_INSTANCES): `Instance` records, the header first (the TLAS
/// root and the instance count), then one per instance.
pub const BINDING_INSTANCES: u32 = 20;
/// The AOVs' running sums (`AovSums`, one per pixel), which the survey stage adds each sample's to; a stand-in where
/// the render asks for none.
pub const BINDING_AOVS: u32 = 21;
/// Adaptive sampling (FEATURE_ADAPTIVE): per pixel the sample index below which it takes samples (plan.comp writes
/// it after the pilot; all ones before), then the largest of them; a stand-in where the render is not adaptive.
pub const BINDING_BUDGET: u32 = 22;
/// The debug views' running sums (`DebugSums`, one per pixel) survey adds when a render asks for one; a stand-in
/// otherwise.
pub const BINDING_DEBUG_AOVS: u32 = 23;
/// The light BVH (`GpuLightNode` records: the header, a leaf per entry of light selection's table, the interior
/// nodes), read when light selection is `bvh`.
pub const BINDING_LIGHT_TREE: u32 = 24;
/// The BVH nodes and the per-triangle buffers again, as uniform texel buffers (RGBA32UI): the TEXEL_READS stage
/// variants read them there, which lavapipe serves much faster than storage-buffer loads in a loop, and which
/// reaches past the device's storage-buffer range (maxTexelBufferElements texels of 16 bytes each). Every binding
/// before BINDING_FIRST_TEXEL is a storage buffer.
pub const BINDING_FIRST_TEXEL: u32 = 25;
pub const BINDING_NODE_TEXELS: u32 = 25;
pub const BINDING_TRI_TEXELS: u32 = 26;
pub const BINDING_TRI_SHADING_TEXELS: u32 = 27;
pub const BINDING_TRI_TEXCOORD_TEXELS: u32 = 28;
pub const BINDING_TRI_TANGENT_TEXELS: u32 = 29;
pub const BINDING_TRI_COLOR_TEXELS: u32 = 30;
/// The textures' RGBA8 texels (one u32 each) as an R32UI view.
pub const BINDING_IMAGE_TEXELS: u32 = 31;
/// The path state (BINDING_PATHS) as a uniform texel buffer (RGBA32F) the TEXEL_READS stages read it through:
/// lavapipe loads a texel per lane at once, where a storage-buffer vec4 is four bounds-checked scalar loads per lane.
/// Writes stay storage-buffer stores (a storage texel buffer's imageStore made shade 60 % slower).
pub const BINDING_PATH_TEXELS: u32 = 32;
/// The materials (BINDING_MATERIALS) as RGBA32UI texels, MATERIAL_TEXELS per material, for the TEXEL_READS stages.
pub const BINDING_MATERIAL_TEXELS: u32 = 33;
/// The light table (BINDING_LIGHTS) as RGBA32UI texels, one per light, for the TEXEL_READS stages.
pub const BINDING_LIGHT_TEXELS: u32 = 34;
/// The motion keys (BINDING_MOTION) as RGBA32UI texels, six per MotionKey, for the TEXEL_READS stages: traversal
/// reads them in its loop, where storage-buffer loads cost the most.
pub const BINDING_MOTION_TEXELS: u32 = 35;
/// The light BVH (BINDING_LIGHT_TREE) as RGBA32UI texels, four per node, for the TEXEL_READS stages.
pub const BINDING_LIGHT_TREE_TEXELS: u32 = 36;
/// The CIE rows of the table buffer (SPECTRUM_CIE) as RGBA32F texels, one per row, for the TEXEL_READS stages:
/// spectral transport reads two rows per wavelength, a texel each, where the storage buffer takes four bounds-checked
/// scalar loads per row on lavapipe (the film's conversion of a sample then cost eight times RGB's accumulate stage).
pub const BINDING_CIE_TEXELS: u32 = 37;
pub const BINDING_COUNT: u32 = 38;
/// The top-level acceleration structure ray-query traversal walks (the RAY_QUERY stage variants): in the shared
/// layout only on devices with ray queries, after the buffers and views.
pub const BINDING_TLAS: u32 = 38;

/// Material texture slots (Material.textures[]).
pub const TEX_BASE_COLOR: u32 = 0;
pub const TEX_METALLIC_ROUGHNESS: u32 = 1;
pub const TEX_NORMAL: u32 = 2;
pub const TEX_EMISSIVE: u32 = 3;
/// KHR_materials_clearcoat: the factor (R), the roughness (G) and the coat's own normal map.
pub const TEX_CLEARCOAT: u32 = 4;
pub const TEX_CLEARCOAT_ROUGHNESS: u32 = 5;
pub const TEX_CLEARCOAT_NORMAL: u32 = 6;
/// KHR_materials_sheen: the colour (sRGB RGB) and the roughness (A).
pub const TEX_SHEEN_COLOR: u32 = 7;
pub const TEX_SHEEN_ROUGHNESS: u32 = 8;
/// KHR_materials_specular: the weight (A) and the colour (sRGB RGB); KHR_materials_transmission: the factor (R).
pub const TEX_SPECULAR: u32 = 9;
pub const TEX_SPECULAR_COLOR: u32 = 10;
pub const TEX_TRANSMISSION: u32 = 11;
/// KHR_materials_anisotropy: a direction in tangent space (RG, linear) and a factor on the strength (B).
pub const TEX_ANISOTROPY: u32 = 12;
/// KHR_materials_iridescence: the factor (R) and the film's thickness between its minimum and maximum (G).
pub const TEX_IRIDESCENCE: u32 = 13;
pub const TEX_IRIDESCENCE_THICKNESS: u32 = 14;
/// KHR_materials_diffuse_transmission: the factor (A) and the colour (sRGB RGB).
pub const TEX_DIFFUSE_TRANSMISSION: u32 = 15;
pub const TEX_DIFFUSE_TRANSMISSION_COLOR: u32 = 16;
/// KHR_materials_diffuse_roughness: the roughness (R).
pub const TEX_DIFFUSE_ROUGHNESS: u32 = 17;
/// KHR_materials_scatter on a thin wall: the strength (A) and the colour (sRGB RGB). The last slots, as only
/// FEATURE_THIN_SCATTER's shaders read them (scene_reads.glsl's load_material).
pub const TEX_SCATTER_STRENGTH: u32 = 18;
pub const TEX_SCATTER_COLOR: u32 = 19;
pub const TEX_SLOTS: u32 = 20;
/// 16-byte texels per material (layout.glsl's Material is 880 bytes).
pub const MATERIAL_TEXELS: u32 = 55;
/// The texel of a material holding its medium (layout.rs checks it against `GpuMaterial`).
pub const MATERIAL_TEXEL_MEDIUM: u32 = 52;
/// The first of a material's two texels of spectral coefficients, read only under FEATURE_SPECTRAL.
pub const MATERIAL_TEXEL_SPECTRA: u32 = 53;
/// A slot without a texture.
pub const TEXTURE_NONE: u32 = 0xFFFFFFFF;
/// TextureInfo.flags: wrap mode along s in bits 0-1, along t in bits 2-3, then the nearest-filter bit, and from
/// TEXTURE_LEVELS_SHIFT the number of mip levels after level 0 (mipmaps.rs; 0 for a sampler without mipmaps).
pub const WRAP_REPEAT: u32 = 0;
pub const WRAP_CLAMP: u32 = 1;
pub const WRAP_MIRROR: u32 = 2;
pub const TEXTURE_WRAP_T_SHIFT: u32 = 2;
pub const TEXTURE_NEAREST: u32 = 16;
pub const TEXTURE_LEVELS_SHIFT: u32 = 8;
pub const TEXTURE_LEVELS_MASK: u32 = 15;

/// ToneMap.op: the viewer's tone curve (low bits) and whether to pack pixels as BGRA instead of RGBA.
pub const TONEMAP_CLAMP: u32 = 0;
pub const TONEMAP_ACES: u32 = 1;
pub const TONEMAP_NEUTRAL: u32 = 2;
pub const TONEMAP_AGX: u32 = 3;
pub const TONEMAP_BGRA: u32 = 16;
/// Workgroups of the 2D tone-map stage are TONEMAP_TILE x TONEMAP_TILE pixels.
pub const TONEMAP_TILE: u32 = 8;

/// Material.alpha.x: glTF alphaMode.
pub const ALPHA_OPAQUE: u32 = 0;
pub const ALPHA_MASK: u32 = 1;
pub const ALPHA_BLEND: u32 = 2;
/// Material.alpha.w bits.
/// KHR_materials_unlit: the surface shows its base colour to every ray that reaches it and scatters nothing.
pub const MATERIAL_UNLIT: u32 = 1;

/// Microfacet energy tables: ENERGY_RES x ENERGY_RES cells over (cos theta, perceptual roughness), each the mean of
/// ENERGY_SAMPLES samples. Layout of the energy buffer, in floats: the E1, E2 and Esheen grids (roughness-major),
/// then the hemispherical averages of each per roughness. E1 is the GGX lobe's albedo with F = 1, E2 its albedo
/// weighted by Schlick's (1 - cos)^5, so a Schlick coat's albedo is F0 E1 + (1 - F0) E2; Esheen is the Charlie sheen
/// lobe's albedo for a white sheen colour, over sheen roughness.
pub const ENERGY_RES: u32 = 32;
pub const ENERGY_SAMPLES: u32 = 4096;
pub const ENERGY_GRIDS: u32 = 3;
/// Samples of the Charlie distribution per Esheen cell.
pub const SHEEN_ENERGY_SAMPLES: u32 = 4096;
pub const ENERGY_TABLE_FLOATS: u32 = ENERGY_GRIDS * ENERGY_RES * ENERGY_RES + ENERGY_GRIDS * ENERGY_RES;
/// The stretched GGX lobe's E1 and E2 (KHR_materials_anisotropy), after the isotropic tables: stretching adds two
/// dimensions (wo's azimuth against the stretch, and a second roughness), so each grid is ANISO_RES_MU cosines x
/// ANISO_RES_PHI azimuths over a quarter turn x ANISO_RES_ROUGH perceptual roughnesses along x the same across, each
/// cell the mean of ANISO_ENERGY_SAMPLES samples; then each grid's hemispherical averages per roughness pair.
pub const ANISO_RES_MU: u32 = 24;
pub const ANISO_RES_PHI: u32 = 16;
pub const ANISO_RES_ROUGH: u32 = 16;
pub const ANISO_ENERGY_SAMPLES: u32 = 512;
pub const ANISO_CELLS: u32 = ANISO_RES_MU * ANISO_RES_PHI * ANISO_RES_ROUGH * ANISO_RES_ROUGH;
pub const ANISO_TABLE_FLOATS: u32 = 2 * ANISO_CELLS + 2 * ANISO_RES_ROUGH * ANISO_RES_ROUGH;
/// The whole energy buffer: the isotropic tables, then the anisotropic ones.
/// Spectral transport's wavelengths, nm: the range they are sampled over, which is the CIE table's
/// (data/cie1931_d65.tsv), as in Mitsuba 3 and pbrt-v4.
pub const LAMBDA_MIN: f32 = 360.0;
pub const LAMBDA_MAX: f32 = 830.0;
/// Wavelengths a path carries (hero wavelength sampling: one drawn, the others at equal offsets of the sampling CDF).
pub const WAVELENGTHS: u32 = 4;
/// The RGB-to-spectrum table's nodes per axis (spectrum::fit; data/rgb2spec_srgb_32.bin): 3 * 32^3 coefficient
/// triples, 1.2 MB. At 64 the mean round-trip error falls from 0.0009 to 0.0002, for 9.4 MB and 50 s of fitting.
pub const RGB2SPEC_RES: u32 = 32;
/// Rows of the CIE table (1 nm from LAMBDA_MIN to LAMBDA_MAX).
pub const CIE_ROWS: u32 = 471;
/// The spectral tables (spectrum.glsl) follow the energy and anisotropic tables in the renderer's table buffer
/// (BINDING_ENERGY), in floats: the XYZ-to-linear-sRGB matrix (three rows of four), zeros up to the next 256 bytes
/// (the largest offset alignment Vulkan allows a texel view, BINDING_CIE_TEXELS), the CIE rows (x, y, z over the
/// integral of y-bar, and D65 scaled to Y = 1), the RGB-to-spectrum table's nodes along its largest component, then
/// its coefficients (spectrum::fit::build_table's layout). The host fills them once per renderer.
pub const SPECTRUM_MATRIX: u32 = ENERGY_TABLE_FLOATS + ANISO_TABLE_FLOATS;
#[allow(clippy::manual_div_ceil)] // exported to GLSL as written
pub const SPECTRUM_CIE: u32 = (SPECTRUM_MATRIX + 12 + 63) / 64 * 64;
pub const SPECTRUM_Z: u32 = SPECTRUM_CIE + 4 * CIE_ROWS;
pub const SPECTRUM_COEFFS: u32 = SPECTRUM_Z + RGB2SPEC_RES;
pub const SPECTRUM_FLOATS: u32 = SPECTRUM_COEFFS + 9 * RGB2SPEC_RES * RGB2SPEC_RES * RGB2SPEC_RES - SPECTRUM_MATRIX;
/// The multiple scattering of the dielectric layer (microsurface.rs, data/dielectric_ms.bin): its albedo E_ms over
/// MS_RES_MU cosines x MS_RES_ROUGH perceptual roughnesses x MS_RES_F0 normal reflectances (square-root spaced), F0-major
/// then roughness, each cell the mean of MS_WALKS random walks; then 2 int E_ms mu dmu per (F0, roughness). After the
/// spectral tables in the table buffer.
pub const MS_RES_MU: u32 = 32;
pub const MS_RES_ROUGH: u32 = 32;
pub const MS_RES_F0: u32 = 10;
pub const MS_WALKS: u32 = 16384;
pub const DIELECTRIC_MS: u32 = SPECTRUM_MATRIX + SPECTRUM_FLOATS;
pub const DIELECTRIC_MS_FLOATS: u32 = MS_RES_MU * MS_RES_ROUGH * MS_RES_F0 + MS_RES_ROUGH * MS_RES_F0;
pub const ENERGY_BUFFER_FLOATS: u32 = ENERGY_TABLE_FLOATS + ANISO_TABLE_FLOATS + SPECTRUM_FLOATS + DIELECTRIC_MS_FLOATS;

/// Frame.flags bits.
pub const FLAG_ENERGY_COMPENSATION: u32 = 1;
/// Camera rays do not see the environment (it still lights the scene).
pub const FLAG_HIDE_ENV: u32 = 2;
/// The scene has COLOR_0 vertex colours (tri_colors is bound): they multiply the base colour.
pub const FLAG_VERTEX_COLORS: u32 = 4;
/// A fused pass (follow.comp): each pixel's running film sums wait in its row-0 slots of PATH_RADIANCE (sum) and
/// PATH_THROUGHPUT (sum of squares), and accumulate copies them to the film unless the pass was cut short.
pub const FLAG_FUSED_SUMS: u32 = 8;
/// The camera is the scene's own and moves over the shutter: camera rays take its keys from the motion buffer
/// instead of the frame's camera (bits 4 and 5 are the estimator's).
pub const FLAG_CAMERA_MOTION: u32 = 64;
/// The camera is orthographic: camera rays start across an image plane frame_half_height() high and all run along
/// its forward axis.
pub const FLAG_ORTHOGRAPHIC: u32 = 128;
// Bits 256, 512 and 1024 are retired: they carried settings no shader reads (the exact film, AOVs, adaptive
// sampling; RenderSettings::features specialises the stages for them). Film files still hash 256 and 1024 into their
// frame fingerprint (session.rs, film_frame_flags), so they must never mean anything else here.
/// survey adds the debug views too (BINDING_DEBUG_AOVS); read by survey, and left out of a film file's frame
/// fingerprint (AOVs do not change the samples).
pub const FLAG_DEBUG_AOVS: u32 = 2048;
/// A pass after adaptive sampling's plan: its pixels are the budget buffer's order (ORDER_*), the pixels by budget
/// from the largest, so a pass covers only those that take its samples and a subgroup's pixels take about as many.
/// plan.comp's second dispatch (which ranks them) carries it too.
pub const FLAG_PIXEL_ORDER: u32 = 4096;
// Bit 8192 is retired (it marked a spectral render); film files hash it, as 256 and 1024 above.
/// Light selection picks uniformly among the table's entries (--light-sampler uniform).
pub const FLAG_LIGHT_UNIFORM: u32 = 16384;
/// Light selection descends the light BVH (--light-sampler bvh, FEATURE_LIGHT_TREE); neither bit: by power.
pub const FLAG_LIGHT_TREE: u32 = 32768;

/// SCENE_FEATURES bits, a specialisation constant (id SPEC_SCENE_FEATURES) the host sets per scene for the render
/// stages: code for what no material or light uses is folded away when the pipeline is built. lavapipe executes both
/// sides of a branch under a mask, so even untaken code costs there. Probe kernels keep every bit (the default) but
/// FEATURE_DEEP_STACK, which they take from the scene.
pub const SPEC_SCENE_FEATURES: u32 = 0;
/// Some material has a dielectric coat (KHR_materials_specular weight above 0).
pub const FEATURE_COAT: u32 = 1;
/// Some material is (partly) metallic.
pub const FEATURE_METAL: u32 = 2;
/// Some material transmits (KHR_materials_transmission).
pub const FEATURE_TRANSMISSION: u32 = 4;
/// The scene has KHR_lights_punctual lights.
pub const FEATURE_PUNCTUAL: u32 = 8;
/// The scene has an environment.
pub const FEATURE_ENV: u32 = 16;
/// A thin lens (aperture > 0): a render setting, not the scene's, so the renderer rebuilds the render stages when a
/// pass changes it. In the fused schedule every bounce runs the camera code for the lanes starting a sample, lens
/// included, whichever lanes need it: folding it away made the Cornell box 3.5 % faster.
pub const FEATURE_LENS: u32 = 32;
/// The traversal stack can hold more than REGISTER_STACK entries (BvhStats::max_waiting): traversal keeps it in
/// memory. Cleared, it lives in REGISTER_STACK registers. Unlike the other bits this one is the BVH's, so the
/// probe_trace kernel takes it from the scene too and the BVH tests check the traversal the render stages run.
pub const FEATURE_DEEP_STACK: u32 = 64;
/// Something moves while the shutter is open (--shutter above 0 on an animated scene): rays carry a time, and
/// traversal, shading, light sampling and the camera interpolate between the MOTION_SEGMENTS + 1 keys.
pub const FEATURE_MOTION: u32 = 128;
/// Some meshes are instanced: after the world BVH, traversal walks a top-level BVH over instances and each one's
/// own BVH in object space, and shading moves the hit into world space (see `Instancing`).
pub const FEATURE_INSTANCES: u32 = 256;
/// Some material has a clear coat (KHR_materials_clearcoat factor above 0): a second GGX lobe over everything else.
pub const FEATURE_CLEARCOAT: u32 = 512;
/// Some material has a sheen (KHR_materials_sheen colour above 0): the Charlie lobe over the base.
pub const FEATURE_SHEEN: u32 = 1024;
/// Some material is unlit (KHR_materials_unlit).
pub const FEATURE_UNLIT: u32 = 2048;
/// Some material is anisotropic (KHR_materials_anisotropy strength above 0): the base's GGX lobes are stretched
/// along a direction in the tangent plane, whose frame shading then builds from the mesh's tangents.
pub const FEATURE_ANISOTROPY: u32 = 4096;
/// Some material is iridescent (KHR_materials_iridescence factor above 0): a thin film's interference in the
/// Fresnel terms of the base's dielectric reflection and metal.
pub const FEATURE_IRIDESCENCE: u32 = 8192;
/// Some material transmits diffusely (KHR_materials_diffuse_transmission factor above 0): part of the base's diffuse
/// lobe goes through the surface (leaves, paper, lamp shades, wax).
pub const FEATURE_DIFFUSE_TRANSMISSION: u32 = 16384;
/// The render keeps the exact film (film.glsl): fixed-point integer sums that merge to the same bits however the
/// samples are split (--film-stats, --samples, --part). A render setting, like FEATURE_LENS; renders without it keep
/// the float film and its speed.
pub const FEATURE_EXACT_FILM: u32 = 32768;
/// Adaptive sampling (--adaptive): a pixel takes sample s only while s is below its budget (BINDING_BUDGET), which
/// plan.comp sets from the pilot samples of its neighbours. A render setting; renders without it keep their speed.
pub const FEATURE_ADAPTIVE: u32 = 65536;
/// Spectral transport (--spectral, and scenes with KHR_materials_dispersion): paths carry WAVELENGTHS wavelengths,
/// colours are upsampled to spectra at them and the film turns them into linear sRGB (spectrum.glsl). A render
/// setting; RGB renders keep their bytes and speed.
pub const FEATURE_SPECTRAL: u32 = 131072;
/// Light selection descends the light BVH (light_tree.glsl): a render setting (FLAG_LIGHT_TREE) for scenes with a
/// tree; renders by power or uniform keep their bytes and speed.
pub const FEATURE_LIGHT_TREE: u32 = 262144;
/// Some material's diffuse lobe is rough (KHR_materials_diffuse_roughness above 0): the energy-preserving
/// Oren-Nayar lobe (EON) replaces the Lambertian one there.
pub const FEATURE_DIFFUSE_ROUGHNESS: u32 = 524288;
/// Some used material has a rough dielectric layer over an opaque base (specular weight, roughness above 0, metallic
/// and transmission below 1 or textured): shading reads the layer's multiple scattering (DIELECTRIC_MS). Without it
/// the table's lookups are not compiled in: lavapipe pays for the code of branches no lane takes (glass.gltf's shade
/// stage ran 3x slower with it).
pub const FEATURE_DIELECTRIC_MS: u32 = 1048576;
/// Some used material is a volume whose medium scatters (KHR_materials_scatter): paths carry the volumes they are inside
/// (PATH_MEDIUM), sample free flights through them and scatter there (media.glsl). Without it, a volume only absorbs,
/// applied where a ray leaves it.
pub const FEATURE_MEDIA: u32 = 2097152;
/// Some used thin-walled material scatters part of its transmission diffusely (KHR_materials_scatter's thin-walled
/// mode): shading reads the material's scatter texel and reshapes its lobes (bsdf.glsl's thin_scatter).
pub const FEATURE_THIN_SCATTER: u32 = 4194304;
/// Minified textures are read from their mip chains (--texture-filter trilinear, the default), at a footprint
/// estimated from the camera (surface.glsl's texture_footprint). A render setting for textured scenes; without it
/// every lookup is bilinear from level 0, the bytes of renders before mip chains existed.
pub const FEATURE_TEXTURE_LOD: u32 = 8388608;
/// Under spectral transport, some colour is neither grey nor known to the host (a texture's, vertex colours, a
/// light's, the environment's, or a material colour without coefficients in its record): shading turns it into a
/// spectrum through the RGB-to-spectrum table. Without it the table's lookups are not compiled in (on lavapipe their
/// code alone, never executed, cost the Cornell box's spectral shade stage a quarter of its time).
pub const FEATURE_SPECTRUM_TABLE: u32 = 16777216;
/// Adaptive sampling's error is relative to a pixel's mean radiance, as if that were at least sqrt of this: relMSE's
/// epsilon (diff::REL_MSE_EPSILON), so near-black pixels do not take every sample to pin down a value no one sees.
pub const ADAPTIVE_EPSILON: f32 = 0.01;
/// The budget buffer (BINDING_BUDGET), in u32 words for P pixels: the budgets [0, P), the pixels by budget from the
/// largest [P, 2P), then per bucket of budgets (ORDER_BUCKETS of them) their count, a cursor plan.comp ranks them with,
/// and their largest. Budgets in one bucket differ by at most 1/8 (layout.glsl's order_bucket: a float of three
/// mantissa bits, exact below 16), and a larger budget never falls in a lower bucket.
pub const ORDER_BUCKETS: u32 = 256;
/// Hit.inst of a world-space triangle (instance records start at 1, after the header).
pub const NO_INSTANCE: u32 = 0;
pub const FEATURES_ALL: u32 = 0xFFFFFFFF;

/// Light ids: the kind in the top two bits, the index (triangle, ...) below.
pub const LIGHT_KIND_SHIFT: u32 = 30;
pub const LIGHT_KIND_TRIANGLE: u32 = 0;
pub const LIGHT_KIND_ENV: u32 = 1;
pub const LIGHT_KIND_PUNCTUAL: u32 = 2;
/// An instance of an emissive mesh (its record's index): a triangle is then picked from the mesh's own table.
pub const LIGHT_KIND_INSTANCE: u32 = 3;

/// PunctualLight.position.w: which KHR_lights_punctual type.
pub const PUNCTUAL_POINT: u32 = 0;
pub const PUNCTUAL_SPOT: u32 = 1;
pub const PUNCTUAL_DIRECTIONAL: u32 = 2;
pub const LIGHT_INDEX_MASK: u32 = 0x3FFFFFFF;
/// GpuLightNode.link[0] of a leaf (an interior node's is its first child).
pub const LIGHT_NODE_LEAF: u32 = 0xFFFFFFFF;
/// probe_light_select's answer when light selection finds nothing that can light the point.
pub const LIGHT_NONE: u32 = 0xFFFFFFFF;
/// Set in GpuLightNode.link[1] (beside an interior node's second child) when the node's cone holds for both faces.
pub const LIGHT_NODE_TWO_SIDED: u32 = 0x80000000;
/// Light selection descends the light BVH (--light-sampler bvh) only for scenes with at least this many emitters in
/// it; below, it picks by power. A descent evaluates two nodes' importance per level for every light sample and
/// again for every emitter a BSDF sample hits, which on the Cornell box (one quad light, two triangles, whose
/// importances stay in the ratio of their powers from almost everywhere) cost 15-30 % of the samples per second for
/// no less noise.
pub const LIGHT_TREE_MIN_EMITTERS: u32 = 8;
/// The deepest leaf of the light BVH: a trail of 64 bits (GpuLightNode.link[2..4]) says which way to turn.
pub const LIGHT_TREE_MAX_DEPTH: u32 = 64;
/// Below this probability of the choices one number made, the light BVH's descent takes its second number: the first
/// has too few of its 24 bits left to choose by.
pub const LIGHT_FRESH_NUMBER_BELOW: f32 = 0.00024414062;
/// Emitters light selection's table may hold: an emissive triangle's TriShading.n0.w holds its entry + 1 as a float,
/// exact up to 2^24.
pub const LIGHT_ENTRIES_MAX: u32 = 16777215;

/// Estimator selection: bits ESTIMATOR_SHIFT.. of Frame.flags.
pub const ESTIMATOR_MIS: u32 = 0;
pub const ESTIMATOR_LIGHT: u32 = 1;
pub const ESTIMATOR_BSDF: u32 = 2;
pub const ESTIMATOR_SHIFT: u32 = 4;

/// Traversal stack depth; the builder guarantees the tree is no deeper than this.
pub const BVH_STACK_SIZE: u32 = 64;
/// Stack entries traversal can keep in registers (FEATURE_DEEP_STACK). lavapipe turns each store to a per-lane
/// indexed array into eight scalar stores, run whether a lane pushes or not; in registers a push is a few selects
/// per entry. The Cornell box (at most 8 entries) traces 6.5 % faster so; a bigger register stack with memory below
/// it, refilled outside the loop, was slower than memory alone on the glass scene (21 entries).
pub const REGISTER_STACK: u32 = 8;
/// A traversal stack entry packs a node as first << STACK_COUNT_BITS | count: leaves hold fewer triangles than
/// 2^STACK_COUNT_BITS, and scenes are limited to 2^(32 - STACK_COUNT_BITS) nodes and triangles (MAX_SCENE_ITEMS).
pub const STACK_COUNT_BITS: u32 = 3;
pub const MAX_SCENE_ITEMS: u32 = 1 << (32 - STACK_COUNT_BITS);
/// Children per interior node in the device layout: a node's children sit in BVH_WIDTH consecutive records (unused
/// ones hold a box no ray enters), and one traversal step tests all of them.
pub const BVH_WIDTH: u32 = 4;
// traverse.glsl and its CPU twin test exactly four children per step and order them with a four-input sorting network.
const _: () = assert!(BVH_WIDTH == 4);
/// Triangles per leaf the SAH builder may create at most.
pub const BVH_MAX_LEAF_TRIS: u32 = 4;
/// A BvhNode child's kind, STACK_COUNT_BITS wide: 0 an unused slot, 1 ..= BVH_MAX_LEAF_TRIS a leaf of that many
/// triangles, BVH_CHILD_INTERIOR an interior node.
pub const BVH_CHILD_INTERIOR: u32 = 7;
const _: () = assert!(BVH_MAX_LEAF_TRIS < BVH_CHILD_INTERIOR && BVH_CHILD_INTERIOR < 1 << STACK_COUNT_BITS);

/// Samples one follow invocation takes through per dispatch, to begin with and at the fewest: lavapipe cuts a shader's
/// loops short once their iterations add up to 65535 per invocation (follow.comp detects it), so a dispatch must not
/// chain too many paths. The renderer doubles it after each fused pass up to FOLLOW_ROWS_MAX, and halves it after a
/// cut: with more samples per invocation, fewer lanes wait for the slowest one's last paths (64 rather than 16 made
/// the Cornell box 2.5 % faster).
pub const FOLLOW_SAMPLES: u32 = 16;
pub const FOLLOW_ROWS_MAX: u32 = 64;

/// Bounce at which Russian roulette starts.
pub const RR_START_BOUNCE: u32 = 3;

/// The AOVs (survey.comp): bounces a camera ray follows through specular surfaces to the first rough one, at most.
pub const AOV_MAX_BOUNCES: u32 = 8;
/// A lobe with a GGX alpha below this (perceptual roughness 0.1) counts as near-specular: the albedo and normal
/// AOVs look through it, as Open Image Denoise asks.
pub const AOV_SPECULAR_ALPHA: f32 = 0.01;
/// An id AOV's value where the sample saw no surface.
pub const AOV_NONE: u32 = 0xFFFFFFFF;

/// Random-number dimensions, so each use of randomness has its own stream.
pub const DIM_PIXEL: u32 = 0;
pub const DIM_LENS: u32 = 1;
/// Next-event estimation: x picks the light and, rescaled, with y places the point on it (lights.glsl).
pub const DIM_LIGHT: u32 = 3;
pub const DIM_BSDF: u32 = 5;
pub const DIM_BSDF_LOBE: u32 = 6;
pub const DIM_RR: u32 = 7;
/// Stochastic transparency (alphaMode BLEND) of extension and shadow rays.
pub const DIM_ALPHA: u32 = 8;
pub const DIM_SHADOW_ALPHA: u32 = 9;
/// The path's time in the shutter (x), drawn once per camera sample.
pub const DIM_TIME: u32 = 10;
/// Set in a path's direction's w (PATH_DIR, beside the instance bits) once a dispersive surface has left it its hero
/// wavelength alone (spectral transport, path.glsl).
pub const PATH_HERO_ONLY: u32 = 0x80000000;
/// The path's hero wavelength (x), drawn once per camera sample (spectrum.glsl).
pub const DIM_WAVELENGTH: u32 = 11;
/// The light BVH's descent (x, then y once x has too few bits left); the point on the light keeps DIM_LIGHT.
pub const DIM_LIGHT_PICK: u32 = 12;
/// Free flights through media: x at bounce 0 the channel whose exponentials draw the path's distances (RGB), y at
/// each bounce the distance.
pub const DIM_MEDIUM: u32 = 13;
/// The direction a medium scatters to (Henyey-Greenstein).
pub const DIM_PHASE: u32 = 14;

/// Segments the shutter is cut into for motion: transforms (and skinned or morphed vertices) are evaluated at
/// MOTION_SEGMENTS + 1 evenly spaced times, vertices move linearly between them. Four keep a quarter turn within the
/// shutter to 0.5 % of its radius (a chord of 22.5 degrees), and linear motion exact.
pub const MOTION_SEGMENTS: u32 = 4;
/// MotionKey records of the camera at the start of the motion buffer, one per key (MOTION_SEGMENTS + 1); triangle
/// t's key k (1 to MOTION_SEGMENTS; key 0 is the triangle buffers') follows at MOTION_CAMERA_KEYS + t *
/// MOTION_SEGMENTS + k - 1.
pub const MOTION_CAMERA_KEYS: u32 = 5;
/// 16-byte texels per MotionKey (96 bytes).
pub const MOTION_KEY_TEXELS: u32 = 6;

/// Queue slots: `ray_count[2]` ping-pong between bounces, then the shadow queue; each queue holds a path index (one
/// u32) per path the path state holds.
pub const QUEUE_SHADOW: u32 = 2;
pub const QUEUE_COUNT: u32 = 3;

/// The film: a vec4 running sum (rgb, sample count in w) per pixel, then a vec4 running sum of squares per pixel.
pub const FILM_BYTES_PER_PIXEL: u32 = 32;

/// The exact film (FEATURE_EXACT_FILM, film.glsl): 16-byte texels per pixel (112 bytes): three 128-bit sums, three
/// 160-bit sums of squares, and the sample count.
pub const EXACT_FILM_TEXELS: u32 = 7;
/// The exact film's sums count units of 2^-EXACT_SUM_BITS: down to 5e-20, and up to 2^63 (9.2e18) in a pixel.
pub const EXACT_SUM_BITS: u32 = 64;
/// Its sums of squares count units of 2^-EXACT_SQUARE_BITS: squares down to 3.6e-15, and up to 2^112 (5.2e33).
pub const EXACT_SQUARE_BITS: u32 = 48;
/// The exact film's count word: set once a pixel's sums overflowed (the host refuses such a film).
pub const EXACT_OVERFLOW: u32 = 0x80000000;

/// Frame.bounce of the probe kernels (probe_mode() in layout.glsl): what each asks of the device function it tests.
pub const PROBE_SAMPLE: u32 = 0;
pub const PROBE_EVALUATE: u32 = 1;
/// probe_trace: closest hit (PROBE_SAMPLE's value) or any hit.
pub const PROBE_ANY_HIT: u32 = 1;
/// probe_bsdf's BsdfProbe.flags.
pub const PROBE_DELTA: u32 = 1;
pub const PROBE_OK: u32 = 2;

/// Path state is SoA: field `f` of path `i` is `paths[f * path_capacity + i]` (one vec4 each).
/// xyz origin, w: solid-angle pdf of the BSDF sample that made this ray (0 for camera rays).
pub const PATH_ORIGIN: u32 = 0;
/// xyz direction, w unused.
pub const PATH_DIR: u32 = 1;
/// rgb throughput, w unused. In a fused pass, a pixel's row-0 slot holds its running film sum of squares instead
/// (FLAG_FUSED_SUMS).
pub const PATH_THROUGHPUT: u32 = 2;
/// rgb radiance gathered by this sample so far, w unused. In a fused pass, a pixel's row-0 slot holds its running
/// film sum instead, the sample count in w (FLAG_FUSED_SUMS).
pub const PATH_RADIANCE: u32 = 3;
/// x: hit distance, y: triangle index bits (NO_HIT on a miss), zw: barycentrics.
pub const PATH_HIT: u32 = 4;
/// xyz shadow-ray origin, w: shadow-ray length.
pub const PATH_SHADOW_ORIGIN: u32 = 5;
/// xyz shadow-ray direction, w unused.
pub const PATH_SHADOW_DIR: u32 = 6;
/// rgb contribution if the shadow ray is unoccluded, w unused.
pub const PATH_SHADOW_RADIANCE: u32 = 7;
pub const PATH_FIELDS: u32 = 8;
/// Under FEATURE_MEDIA only, allocated after the PATH_FIELDS every path has: the volumes the ray is inside (uint bits,
/// media.glsl's stack).
pub const PATH_MEDIUM: u32 = 8;
/// Under FEATURE_MEDIA only: each channel's density of the path's free flights over their mean (media.glsl's
/// medium_sample).
pub const PATH_MEDIUM_RATIOS: u32 = 9;

/// The largest radiance per channel one sample may add to the film; film_add (layout.glsl) drops a sample beyond
/// it, or not finite, and counts it (Counters::nonfinite). Its square is 1e30, so even 2^24 samples (the spp limit)
/// at the limit sum to 1.7e37 and the film's sum of squares stays finite in f32.
pub const SAMPLE_RADIANCE_MAX: f32 = 1.0e15;

/// Triangle index meaning "no hit".
pub const NO_HIT: u32 = 0xFFFFFFFF;
