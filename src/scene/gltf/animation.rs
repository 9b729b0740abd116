//! Animations, skins, morph targets and vertex joints: each accessor checked as meshes' are, each keyframe set
//! checked so that sampling cannot fail; a channel that cannot play is dropped with a warning.
use super::meshes::Contents;
use super::{scene_err, Loader};
use crate::error::Error;
use crate::scene::animation::{Animation, Channel, Interpolation, Property, Sampler};
use crate::scene::pointer::{self, Target};
use crate::scene::rig::Skin;
use crate::scene::{JointSet, MorphTarget, Primitive};
use glam::{Mat4, Vec3, Vec4};
use gltf::accessor::{DataType, Dimensions};

const NORMALIZED_INTS: [DataType; 5] = [DataType::F32, DataType::I8, DataType::U8, DataType::I16, DataType::U16];

impl Loader<'_> {
    pub(super) fn animations(&mut self, doc: &gltf::Document) -> Result<Vec<Animation>, Error> {
        let counts = [
            doc.nodes().len(),
            doc.materials().len(),
            doc.lights().map_or(0, |l| l.len()),
            doc.cameras().len(),
        ];
        let mut animations = Vec::new();
        for a in doc.animations() {
            let name = a.name().unwrap_or_default().to_string();
            // (channel index, what it drives or why it cannot, its sampler), in the file's channel order.
            let mut found: Vec<(usize, Result<Target, String>, gltf::animation::Sampler)> = Vec::new();
            for c in a.channels() {
                // gltf's Target unwraps both: a file may name a node that does not exist or a path it cannot read.
                let target = &doc.as_json().animations[a.index()].channels[c.index()].target;
                let node = target.node.value();
                let property = match target.path {
                    _ if node >= doc.nodes().len() => Err(format!("its target node {node} does not exist")),
                    gltf::json::validation::Checked::Valid(p) => Ok(match p {
                        gltf::json::animation::Property::Translation => Property::Translation,
                        gltf::json::animation::Property::Rotation => Property::Rotation,
                        gltf::json::animation::Property::Scale => Property::Scale,
                        gltf::json::animation::Property::MorphTargetWeights => Property::Weights,
                    }),
                    _ => Err("its target path is not translation, rotation, scale, weights or pointer".to_string()),
                };
                found.push((c.index(), property.map(|p| Target::Node(node, p)), c.sampler()));
            }
            // Channels without a node were taken out before parsing; KHR_animation_pointer's come back here.
            for u in self.untargeted.iter().filter(|u| u.animation == a.index()) {
                let Some(sampler) = a.samplers().nth(u.sampler) else {
                    continue;
                };
                let target = match &u.pointer {
                    Some(p) => pointer::parse(p, counts).map_err(|why| format!("its pointer {p}: {why}")),
                    None => Err("it has no target node or pointer".to_string()),
                };
                found.push((u.channel, target, sampler));
            }
            found.sort_by_key(|f| f.0);
            let mut channels = Vec::new();
            for (c, target, sampler) in found {
                let channel = match target {
                    Ok(target) => self.channel(target, &sampler)?,
                    Err(why) => Err(why),
                };
                match channel {
                    Ok(channel) => channels.push(channel),
                    Err(why) => self.warn(format!(
                        "animation {} channel {c}: {why}; the channel is ignored",
                        a.index()
                    )),
                }
            }
            animations.push(Animation { name, channels });
        }
        Ok(animations)
    }

    /// One channel, an error for a malformed accessor, or why its keys cannot play (the inner Err).
    fn channel(&self, target: Target, sampler: &gltf::animation::Sampler) -> Result<Result<Channel, String>, Error> {
        let interpolation = match key_interpolation(target, sampler) {
            Ok(interpolation) => interpolation,
            Err(why) => return Ok(Err(why)),
        };
        let (input, output) = (sampler.input(), sampler.output());
        let inputs = self.check_accessor(&input, "animation input", &[DataType::F32], Dimensions::Scalar, false)?;
        let (types, dims) = output_types(target);
        let outputs = match self.check_output(target, &output, types, dims)? {
            Ok(outputs) => outputs,
            Err(why) => return Ok(Err(why)),
        };
        if inputs == Contents::Zeros {
            return Ok(Err("its input accessor has no data".into()));
        }
        let times: Vec<f32> = self.read_scalars(&input).unwrap_or_default();
        if times.len() != input.count() {
            return Ok(Err("its input accessor cannot be read".into()));
        }
        if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| w[0] >= w[1]) {
            return Ok(Err("its key times are not finite and strictly increasing".into()));
        }
        let per_key = if interpolation == Interpolation::CubicSpline {
            3
        } else {
            1
        };
        let width = match target.width() {
            Some(w) => w,
            // One weight per target: the output holds keys times targets of them.
            None => {
                let elements = times.len() * per_key;
                if output.count() % elements != 0 {
                    return Ok(Err(format!(
                        "its {} weights are not a whole number per key ({} keys)",
                        output.count(),
                        times.len()
                    )));
                }
                output.count() / elements
            }
        };
        let Some(values) = self.output_values(&output, outputs, dims) else {
            return Ok(Err("its output accessor cannot be read".into()));
        };
        if values.len() != times.len() * per_key * width {
            return Ok(Err(format!(
                "it has {} keys but {} output values ({} expected)",
                times.len(),
                values.len() / width.max(1),
                times.len() * per_key
            )));
        }
        if values.iter().any(|v| !v.is_finite()) {
            return Ok(Err("an output value is not finite".into()));
        }
        if let Target::Node(node, Property::Weights) = target {
            let targets = self.scene.rig.nodes[node].weights.len();
            if width != targets {
                return Ok(Err(format!(
                    "it drives {width} morph weights, but node {node}'s mesh has {targets} morph targets"
                )));
            }
        }
        Ok(Ok(Channel {
            target,
            sampler: Sampler {
                interpolation,
                times,
                values,
                width,
            },
        }))
    }

    /// What the output accessor holds, checked against `types` and `dims`: an error for a malformed accessor, why
    /// the channel cannot play (the inner Err) for a pointer's output of another type than its property's.
    fn check_output(
        &self,
        target: Target,
        output: &gltf::Accessor,
        types: &[DataType],
        dims: Dimensions,
    ) -> Result<Result<Contents, String>, Error> {
        let outputs = if matches!(target, Target::Node(..)) {
            self.check_accessor(output, "animation output", types, dims, true)?
        } else if !types.contains(&output.data_type()) || output.dimensions() != dims {
            // A pointer's type is its property's; another is the file's mistake, dropped as its channel.
            return Ok(Err(format!(
                "its output is {:?} of {:?}, where its property takes {dims:?} of {types:?}",
                output.dimensions(),
                output.data_type()
            )));
        } else {
            self.check_accessor(output, "animation output", types, dims, output.normalized())?
        };
        Ok(Ok(outputs))
    }

    /// The output's values, `dims` at a time (zeros for an accessor without data); None when they cannot be read.
    fn output_values(&self, output: &gltf::Accessor, outputs: Contents, dims: Dimensions) -> Option<Vec<f32>> {
        if outputs == Contents::Zeros {
            Some(vec![0.0; output.count() * dims.multiplicity()])
        } else {
            match dims {
                Dimensions::Vec2 => self.read_floats::<2>(output).map(|v| v.concat()),
                Dimensions::Vec3 => self.read_floats::<3>(output).map(|v| v.concat()),
                Dimensions::Vec4 => self.read_floats::<4>(output).map(|v| v.concat()),
                _ => self.read_scalars(output),
            }
        }
    }

    /// EXT_mesh_gpu_instancing's per-instance transforms of a node (empty without the extension): TRANSLATION,
    /// ROTATION and SCALE accessors of one count, each optional.
    pub(super) fn instancing(&self, node: &gltf::Node) -> Result<Vec<Mat4>, Error> {
        let Some(ext) = node.extension_value("EXT_mesh_gpu_instancing") else {
            return Ok(Vec::new());
        };
        let err = |m: String| {
            scene_err(
                self.path,
                format!("node {} (EXT_mesh_gpu_instancing): {m}", node.index()),
            )
        };
        let attributes = ext.get("attributes").and_then(|a| a.as_object());
        let Some(attributes) = attributes else {
            return Err(err("it has no attributes".into()));
        };
        let doc = self.document;
        let mut count: Option<usize> = None;
        let mut columns: [Option<Vec<Vec4>>; 3] = [None, None, None];
        for (slot, name) in ["TRANSLATION", "ROTATION", "SCALE"].iter().enumerate() {
            let Some(index) = attributes.get(*name) else { continue };
            let acc = index
                .as_u64()
                .and_then(|i| doc.accessors().nth(i as usize))
                .ok_or_else(|| err(format!("{name} names accessor {index}, which does not exist")))?;
            let (types, dims): (&[DataType], Dimensions) = match *name {
                "ROTATION" => (&[DataType::F32, DataType::I8, DataType::I16], Dimensions::Vec4),
                _ => (&[DataType::F32], Dimensions::Vec3),
            };
            let contents = self.check_accessor(&acc, name, types, dims, true)?;
            let n = acc.count();
            if count.is_some_and(|c| c != n) {
                return Err(err(format!("{name} has {n} elements where the others have {count:?}")));
            }
            count = Some(n);
            let buffers = self.buffers;
            let data = |b: gltf::Buffer| buffers.get(b.index()).map(|d| &d[..]);
            let values: Vec<Vec4> = match (contents, acc.data_type()) {
                (Contents::Zeros, _) => vec![Vec4::ZERO; n],
                (_, DataType::F32) if dims == Dimensions::Vec3 => gltf::accessor::Iter::<[f32; 3]>::new(acc, data)
                    .map(|i| i.map(|v| Vec3::from(v).extend(0.0)).collect())
                    .unwrap_or_default(),
                (_, DataType::F32) => gltf::accessor::Iter::<[f32; 4]>::new(acc, data)
                    .map(|i| i.map(Vec4::from).collect())
                    .unwrap_or_default(),
                (_, DataType::I8) => gltf::accessor::Iter::<[i8; 4]>::new(acc, data)
                    .map(|i| i.map(|v| Vec4::from(v.map(|c| (c as f32 / 127.0).max(-1.0)))).collect())
                    .unwrap_or_default(),
                _ => gltf::accessor::Iter::<[i16; 4]>::new(acc, data)
                    .map(|i| {
                        i.map(|v| Vec4::from(v.map(|c| (c as f32 / 32767.0).max(-1.0))))
                            .collect()
                    })
                    .unwrap_or_default(),
            };
            if values.len() != n || values.iter().any(|v| !v.is_finite()) {
                return Err(err(format!("{name} cannot be read or holds a non-finite value")));
            }
            columns[slot] = Some(values);
        }
        let n = count.ok_or_else(|| err("it names none of TRANSLATION, ROTATION and SCALE".into()))?;
        let [t, r, s] = columns;
        Ok((0..n)
            .map(|i| {
                let translation = t.as_ref().map_or(Vec3::ZERO, |t| t[i].truncate());
                let rotation = r.as_ref().map_or(glam::Quat::IDENTITY, |r| {
                    let q = glam::Quat::from_vec4(r[i]);
                    // An all-zero rotation (an accessor without data) is no rotation.
                    if q.length_squared() > 0.0 {
                        q.normalize()
                    } else {
                        glam::Quat::IDENTITY
                    }
                });
                let scale = s.as_ref().map_or(Vec3::ONE, |s| s[i].truncate());
                Mat4::from_scale_rotation_translation(scale, rotation, translation)
            })
            .collect())
    }

    pub(super) fn skin(&self, s: &gltf::Skin) -> Result<Skin, Error> {
        let joints: Vec<usize> = s.joints().map(|j| j.index()).collect();
        let err = |m: String| scene_err(self.path, format!("skin {}: {m}", s.index()));
        let inverse_bind = match s.inverse_bind_matrices() {
            None => vec![Mat4::IDENTITY; joints.len()],
            Some(acc) => {
                let contents =
                    self.check_accessor(&acc, "inverseBindMatrices", &[DataType::F32], Dimensions::Mat4, false)?;
                if acc.count() < joints.len() {
                    return Err(err(format!(
                        "{} inverse bind matrices for {} joints",
                        acc.count(),
                        joints.len()
                    )));
                }
                let buffers = self.buffers;
                let read: Vec<Mat4> = match contents {
                    Contents::Zeros => vec![Mat4::ZERO; joints.len()],
                    Contents::Data => s
                        .reader(|b| buffers.get(b.index()).map(|d| &d[..]))
                        .read_inverse_bind_matrices()
                        .map(|m| m.map(|m| Mat4::from_cols_array_2d(&m)).collect())
                        .unwrap_or_default(),
                };
                if read.iter().any(|m| !m.is_finite()) {
                    return Err(err("an inverse bind matrix is not finite".into()));
                }
                read
            }
        };
        Ok(Skin {
            name: s.name().unwrap_or_default().to_string(),
            joints,
            inverse_bind,
        })
    }

    /// The primitive's morph targets and joint sets, checked against its vertex count.
    pub(super) fn read_deformation(
        &self,
        mesh_name: &str,
        prim: &gltf::Primitive,
        p: &mut Primitive,
    ) -> Result<(), Error> {
        self.read_morph_targets(mesh_name, prim, p)?;
        self.read_joint_sets(mesh_name, prim, p)
    }

    /// Appends the primitive's morph targets to `p`, every target's accessors checked before any is read.
    fn read_morph_targets(&self, mesh_name: &str, prim: &gltf::Primitive, p: &mut Primitive) -> Result<(), Error> {
        let err = |m: String| scene_err(self.path, format!("mesh '{mesh_name}': {m}"));
        let n = p.positions.len();
        for (t, target) in prim.morph_targets().enumerate() {
            for (what, acc) in [
                ("POSITION", target.positions()),
                ("NORMAL", target.normals()),
                ("TANGENT", target.tangents()),
            ] {
                if let Some(acc) = acc {
                    let what = format!("morph target {t} {what}");
                    // One without data displaces nothing, and gltf's reader yields nothing for it: the same.
                    self.check_attribute(&acc, &what, super::quantized::MORPH_TYPES, Dimensions::Vec3)?;
                    if acc.count() != n {
                        return Err(err(format!("{what} has {} elements for {n} vertices", acc.count())));
                    }
                }
            }
        }
        for (t, target) in prim.morph_targets().enumerate() {
            let read = |v: Option<gltf::Accessor>| {
                v.and_then(|a| self.read_floats::<3>(&a))
                    .map(|v| v.into_iter().map(Vec3::from).collect::<Vec<_>>())
            };
            let target = MorphTarget {
                positions: read(target.positions()),
                normals: read(target.normals()),
                tangents: read(target.tangents()),
            };
            let all = [&target.positions, &target.normals, &target.tangents];
            if all.iter().copied().flatten().flatten().any(|v| !v.is_finite()) {
                return Err(err(format!("morph target {t} holds a non-finite value")));
            }
            p.morph_targets.push(target);
        }
        Ok(())
    }

    /// Appends the primitive's joint sets (JOINTS_n with WEIGHTS_n, from set 0 up to the first missing) to `p`.
    fn read_joint_sets(&self, mesh_name: &str, prim: &gltf::Primitive, p: &mut Primitive) -> Result<(), Error> {
        let err = |m: String| scene_err(self.path, format!("mesh '{mesh_name}': {m}"));
        let n = p.positions.len();
        let buffers = self.buffers;
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d[..]));
        for set in 0.. {
            let (Some(j), Some(w)) = (
                prim.get(&gltf::Semantic::Joints(set)),
                prim.get(&gltf::Semantic::Weights(set)),
            ) else {
                break;
            };
            let jc = self.check_accessor(
                &j,
                &format!("JOINTS_{set}"),
                &[DataType::U8, DataType::U16],
                Dimensions::Vec4,
                false,
            )?;
            let wc = self.check_accessor(
                &w,
                &format!("WEIGHTS_{set}"),
                &[DataType::F32, DataType::U8, DataType::U16],
                Dimensions::Vec4,
                true,
            )?;
            if j.count() != n || w.count() != n {
                return Err(err(format!(
                    "JOINTS_{set} or WEIGHTS_{set} and POSITION have different counts"
                )));
            }
            let joints: Vec<[u16; 4]> = match jc {
                Contents::Zeros => vec![[0; 4]; n],
                Contents::Data => reader
                    .read_joints(set)
                    .map(|r| r.into_u16().collect())
                    .unwrap_or_default(),
            };
            let weights: Vec<Vec4> = match wc {
                Contents::Zeros => vec![Vec4::ZERO; n],
                Contents::Data => reader
                    .read_weights(set)
                    .map(|r| r.into_f32().map(Vec4::from).collect())
                    .unwrap_or_default(),
            };
            if weights.iter().any(|w| !w.is_finite() || w.min_element() < 0.0) {
                return Err(err(format!("WEIGHTS_{set} holds a negative or non-finite weight")));
            }
            p.skin.push(JointSet { joints, weights });
        }
        Ok(())
    }
}

/// The keys' interpolation: STEP for visibility whatever the sampler says, and why the channel cannot play when
/// visibility's keys are a cubic spline.
fn key_interpolation(target: Target, sampler: &gltf::animation::Sampler) -> Result<Interpolation, String> {
    let mut interpolation = match sampler.interpolation() {
        gltf::animation::Interpolation::Step => Interpolation::Step,
        gltf::animation::Interpolation::Linear => Interpolation::Linear,
        gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
    };
    if let Target::Visible(_) = target {
        // Visibility is on or off: its keys hold until the next, whatever the sampler says.
        if interpolation == Interpolation::CubicSpline {
            return Err("its visibility keys are a cubic spline, which a boolean cannot follow".into());
        }
        interpolation = Interpolation::Step;
    }
    Ok(interpolation)
}

/// The component types and dimensions a channel's output may have for what it drives.
fn output_types(target: Target) -> (&'static [DataType], Dimensions) {
    match target.width() {
        Some(2) => (&[DataType::F32], Dimensions::Vec2),
        Some(3) => (&[DataType::F32], Dimensions::Vec3),
        Some(4) if target.rotation() => (&NORMALIZED_INTS, Dimensions::Vec4),
        Some(4) => (&[DataType::F32], Dimensions::Vec4),
        None => (&NORMALIZED_INTS, Dimensions::Scalar),
        _ if matches!(target, Target::Visible(_)) => (&[DataType::F32, DataType::U8], Dimensions::Scalar),
        _ => (&[DataType::F32], Dimensions::Scalar),
    }
}
