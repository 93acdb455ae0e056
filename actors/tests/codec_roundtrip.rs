//! Every wire message round-trips through the codec unchanged (proptest), and any
//! split of the byte stream decodes to the same messages.

use bytes::BytesMut;
use glam::{Quat, Vec2, Vec3};
use gridlight_actors::codec::{MasterCodec, WorkerCodec};
use gridlight_actors::protocol::*;
use gridlight_actors::state::*;
use proptest::prelude::*;
use tokio_util::codec::{Decoder, Encoder};

fn vec3() -> impl Strategy<Value = Vec3> {
    (-1e3f32..1e3, -1e3f32..1e3, -1e3f32..1e3).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

fn light() -> impl Strategy<Value = Light> {
    prop_oneof![
        (vec3(), vec3()).prop_map(|(position, intensity)| Light::Point { position, intensity }),
        (vec3(), vec3(), vec3(), 0f32..90.0).prop_map(|(position, direction, intensity, a)| {
            Light::Spot { position, direction, intensity, inner_deg: a / 2.0, outer_deg: a }
        }),
        (vec3(), vec3(), 0f32..5.0).prop_map(|(direction, radiance, r)| Light::Sun {
            direction,
            radiance,
            angular_radius_deg: r
        }),
        (vec3(), vec3(), vec3(), vec3()).prop_map(|(corner, edge_u, edge_v, radiance)| {
            Light::Quad { corner, edge_u, edge_v, radiance }
        }),
    ]
}

fn geometry() -> impl Strategy<Value = Geometry> {
    prop_oneof![
        "[a-z/]{1,20}\\.obj".prop_map(|path| Geometry::Obj { path }),
        "[a-z/]{1,20}\\.glb".prop_map(|path| Geometry::Gltf { path }),
        Just(Geometry::Quad),
        Just(Geometry::Cube),
        (0u32..6).prop_map(|subdivisions| Geometry::Sphere { subdivisions }),
    ]
}

fn object() -> impl Strategy<Value = Object> {
    (
        "[a-z_]{1,12}",
        geometry(),
        vec3(),
        vec3(),
        prop::collection::vec(0u32..8, 0..4),
        any::<bool>(),
    )
        .prop_map(|(name, geometry, translation, scale, materials, visible)| Object {
            name,
            geometry,
            transform: Transform { translation, rotation: Quat::from_rotation_y(0.3), scale },
            materials,
            visible,
        })
}

fn material() -> impl Strategy<Value = Material> {
    let kind = prop_oneof![
        Just(MaterialKind::Diffuse),
        Just(MaterialKind::Conductor),
        Just(MaterialKind::Glossy),
        Just(MaterialKind::Dielectric),
        Just(MaterialKind::Pbr)
    ];
    let alpha_mode =
        prop_oneof![Just(AlphaMode::Opaque), Just(AlphaMode::Mask), Just(AlphaMode::Blend)];
    let map = || prop::option::of("[a-z]{1,8}\\.png");
    let base = ("[a-z]{1,8}", kind, vec3(), map(), 0f32..1.0, 1f32..2.5, vec3(), 0f32..10.0);
    let pbr = (0f32..1.0, 0f32..1.0, 0f32..1.0, alpha_mode, 0f32..1.0, any::<bool>());
    let maps = (map(), map(), 0f32..2.0, map());
    let wrap =
        || prop_oneof![Just(Wrap::Repeat), Just(Wrap::ClampToEdge), Just(Wrap::MirroredRepeat)];
    let lookup =
        (wrap(), wrap(), -2f32..2.0, -4f32..4.0, 0.1f32..3.0).prop_map(|(s, t, o, r, k)| {
            MapLookup {
                wrap: [s, t],
                offset: Vec2::new(o, -o),
                rotation: r,
                scale: Vec2::new(k, 1.0),
            }
        });
    (base, pbr, maps, lookup).prop_map(|(base, pbr, maps, lookup)| {
        let (name, kind, base_color, base_color_texture, roughness, ior, emission, strength) = base;
        let (metallic, transmission, alpha, alpha_mode, alpha_cutoff, double_sided) = pbr;
        let (metallic_roughness_texture, normal_texture, normal_scale, emissive_texture) = maps;
        Material {
            name,
            kind,
            base_color,
            base_color_texture,
            roughness,
            ior,
            emission,
            emission_strength: strength,
            metallic,
            transmission,
            alpha,
            alpha_mode,
            alpha_cutoff,
            double_sided,
            metallic_roughness_texture,
            normal_texture,
            normal_scale,
            emissive_texture,
            lookups: MapLookups { normal: lookup, ..MapLookups::default() },
        }
    })
}

fn scene_state() -> impl Strategy<Value = SceneState> {
    (
        any::<u64>(),
        any::<u64>(),
        (1u32..4096, 1u32..4096),
        (vec3(), vec3(), 1f32..170.0),
        prop::collection::vec(object(), 0..4),
        prop::collection::vec(material(), 0..4),
        prop::collection::vec(light(), 0..4),
        prop::option::of((prop::option::of("[a-z]{1,8}\\.hdr"), vec3(), 0f32..10.0, 0f32..360.0)),
        (1u32..16, 1u32..64),
    )
        .prop_map(
            |(
                version,
                seed,
                (width, height),
                (position, look_at, vfov_deg),
                objects,
                materials,
                lights,
                env,
                (max_depth, spp),
            )| {
                SceneState {
                    version,
                    seed,
                    resolution: Resolution { width, height },
                    camera: Camera {
                        position,
                        look_at,
                        up: Vec3::Y,
                        vfov_deg,
                        aperture: 0.0,
                        focus_distance: 1.0,
                    },
                    objects,
                    materials,
                    lights,
                    environment: env.map(|(map, color, intensity, rotation_deg)| Environment {
                        map,
                        color,
                        intensity,
                        rotation_deg,
                    }),
                    render: RenderSettings { max_depth, spp },
                }
            },
        )
}

fn hash() -> impl Strategy<Value = [u8; 32]> {
    any::<[u8; 32]>()
}

fn worker_msg() -> impl Strategy<Value = WorkerMsg> {
    prop_oneof![
        (any::<u32>(), ".{0,40}", any::<u32>())
            .prop_map(|(protocol, name, cores)| WorkerMsg::Hello { protocol, name, cores }),
        prop::option::of(hash()).prop_map(|mac| WorkerMsg::Auth { mac }),
        hash().prop_map(|hash| WorkerMsg::AssetRequest { hash }),
        any::<u32>().prop_map(|credits| WorkerMsg::Ready { credits }),
        (
            any::<u64>(),
            any::<u32>(),
            any::<u64>(),
            prop::collection::vec(any::<u32>(), 0..300),
            any::<u64>(),
            prop::option::of(any::<[u8; gridlight_actors::integrity::TAG_LEN]>()),
        )
            .prop_map(|(frame, set, state_version, px, render_us, tag)| WorkerMsg::Result(
                JobResult {
                    frame,
                    set,
                    state_version,
                    radiance: PackedRadiance::Rgb9e5(px),
                    render_us,
                    tag,
                }
            )),
        Just(WorkerMsg::Heartbeat),
        (0f32..100.0, 0f32..1e4).prop_map(|(percent, window_s)| WorkerMsg::Paused {
            reason: PauseReason::OwnerCpu { percent, window_s }
        }),
        (0f32..1e6).prop_map(|seconds_ago| WorkerMsg::Paused {
            reason: PauseReason::OwnerInput { seconds_ago }
        }),
        Just(WorkerMsg::Resumed),
        (any::<u64>(), any::<u32>()).prop_map(|(frame, set)| WorkerMsg::Superseded { frame, set }),
        (any::<u32>(), prop::collection::vec(any::<u8>(), 0..64))
            .prop_map(|(protocol, noise)| WorkerMsg::Handshake { protocol, noise }),
    ]
}

fn master_msg() -> impl Strategy<Value = MasterMsg> {
    let partition = prop_oneof![Just(Partition::QuasiRandom), Just(Partition::Tiles)];
    let entry = ("[a-z/]{1,16}", hash(), any::<u64>()).prop_map(|(path, hash, len)| AssetEntry {
        path,
        hash,
        len,
    });
    prop_oneof![
        (hash(), any::<bool>())
            .prop_map(|(nonce, auth_required)| MasterMsg::Challenge { nonce, auth_required }),
        ".{0,80}".prop_map(|reason| MasterMsg::Rejected { reason }),
        (any::<u64>(), 1u32..1024, partition, prop::collection::vec(entry, 0..4)).prop_map(
            |(worker_id, sets, partition, assets)| MasterMsg::Welcome {
                worker_id,
                sets: SetsConfig { sets, partition },
                assets
            }
        ),
        (hash(), any::<u64>(), any::<u64>(), prop::collection::vec(any::<u8>(), 0..2000)).prop_map(
            |(hash, offset, len, data)| MasterMsg::AssetChunk { hash, offset, len, data }
        ),
        scene_state().prop_map(|s| MasterMsg::State(Box::new(s))),
        (any::<u64>(), any::<u32>(), any::<u64>(), any::<u32>()).prop_map(
            |(frame, set, state_version, spp)| MasterMsg::Job { frame, set, state_version, spp }
        ),
        Just(MasterMsg::Heartbeat),
        prop::collection::vec(any::<u8>(), 0..64).prop_map(|noise| MasterMsg::Handshake { noise }),
    ]
}

proptest! {
    #[test]
    fn worker_messages_roundtrip(msgs in prop::collection::vec(worker_msg(), 1..5), split in 0usize..4096) {
        let mut buf = BytesMut::new();
        let mut enc = WorkerCodec::new();
        for m in &msgs {
            enc.encode(m, &mut buf).expect("encode");
        }
        // Feed the stream in two pieces at an arbitrary point.
        let split = split.min(buf.len());
        let tail = buf.split_off(split);
        let mut dec = MasterCodec::new();
        let mut got = Vec::new();
        while let Some(m) = dec.decode(&mut buf).expect("decode") { got.push(m); }
        buf.unsplit(tail);
        while let Some(m) = dec.decode(&mut buf).expect("decode") { got.push(m); }
        prop_assert_eq!(got, msgs);
        prop_assert!(buf.is_empty());
    }

    #[test]
    fn master_messages_roundtrip(msg in master_msg()) {
        let mut buf = BytesMut::new();
        MasterCodec::new().encode(&msg, &mut buf).expect("encode");
        let got = WorkerCodec::new().decode(&mut buf).expect("decode");
        prop_assert_eq!(got, Some(msg));
        prop_assert!(buf.is_empty());
    }
}
