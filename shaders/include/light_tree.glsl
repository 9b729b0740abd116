// The light BVH on the device (FEATURE_LIGHT_TREE): a node's importance at a point, the descent that picks an emitter
// and its pdf twin. src/bvh/lights/pick.rs is the CPU twin and does the same arithmetic in the same order.
#ifndef LIGHT_TREE_GLSL
#define LIGHT_TREE_GLSL

// cos(max(0, a - b)) and sin(max(0, a - b)) from the sines and cosines of a and b.
float cos_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
    return cos_a > cos_b ? 1.0 : cos_a * cos_b + sin_a * sin_b;
}
float sin_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
    return cos_a > cos_b ? 0.0 : sin_a * cos_b - cos_a * sin_b;
}

// A bound on what the node's emitters can send to p on a surface with normal n (zero: no receiver term): power over
// squared distance times the cosines left at the emitter (after the normal cone and the bounds' angular size) and at
// the receiver. Zero only where no emitter below the node can light p (tested in src/bvh/lights/tests.rs).
float light_importance(uint node, bool two_sided, vec3 p, vec3 n) {
    vec4 sphere = light_node_sphere(node);
    vec4 cone = light_node_cone(node);
    vec4 angles = light_node_angles(node);
    vec3 to_p = p - sphere.xyz;
    float d2_true = dot(to_p, to_p);
    float r2 = sphere.w * sphere.w;
    // Inside the sphere the distance says nothing: its radius stands for it.
    float d2 = max(max(d2_true, r2), 1e-20);
    float inv_d = inversesqrt(max(d2_true, 1e-30));
    vec3 wi = to_p * inv_d;
    float cos_w = dot(cone.xyz, wi);
    if (two_sided) cos_w = abs(cos_w);
    float sin_w = sqrt(max(0.0, 1.0 - cos_w * cos_w));
    // The half angle the sphere spans from p: all directions from inside it.
    bool inside = d2_true <= r2;
    float sin_b = inside ? 0.0 : sphere.w * inv_d;
    float cos_b = inside ? -1.0 : sqrt(max(0.0, 1.0 - sin_b * sin_b));
    float cos_x = cos_sub_clamped(sin_w, cos_w, angles.y, angles.x);
    float sin_x = sin_sub_clamped(sin_w, cos_w, angles.y, angles.x);
    float cos_p = cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
    if (cos_p <= angles.z) return 0.0;
    float imp = cone.w * cos_p / d2;
    if (n != vec3(0.0)) {
        float cos_i = abs(dot(wi, n));
        float sin_i = sqrt(max(0.0, 1.0 - cos_i * cos_i));
        imp *= cos_sub_clamped(sin_i, cos_i, sin_b, cos_b);
    }
    return clamp(imp, 0.0, 1e30);
}

// The probability of an interior node's first child at (p, n); -1 when neither child can light p.
float light_first_child(uvec4 link, vec3 p, vec3 n) {
    // A child's two-sidedness rides in its parent's link, so importance reads three of a node's four texels.
    float i0 = light_importance(link.x, (link.z & 1u) != 0u, p, n);
    float i1 = light_importance(link.y & ~LIGHT_NODE_TWO_SIDED, (link.y & LIGHT_NODE_TWO_SIDED) != 0u, p, n);
    return i0 + i1 > 0.0 ? i0 / (i0 + i1) : -1.0;
}

// The random numbers of one descent, through the tree and on into an instanced mesh's subtree: x chooses, rescaled
// at each node, until the choices it made are less likely than LIGHT_FRESH_NUMBER_BELOW, where y (an independent
// number with all its bits) takes over; 24 bits then keep each pick within about 2^-12 of its pmf.
struct LightWalk {
    float x;
    float y;
    float part;
    bool fresh;
};

LightWalk light_walk(vec2 u) {
    LightWalk w;
    w.x = u.x;
    w.y = u.y;
    w.part = 1.0;
    w.fresh = false;
    return w;
}

// Descends from `node` (the root, or an instanced mesh's subtree's root with p and n in the mesh's space) by
// importance at (p, n): the leaf's table entry and the probability of reaching it from `node`; false when nothing
// below `node` can light p.
bool tree_descend(uint node, vec3 p, vec3 n, inout LightWalk w, out uint entry, out float prob) {
    entry = 0u;
    prob = 0.0;
    if (node == 0u) return false;
    float pr = 1.0;
    uvec4 link = light_node_link(node);
    for (uint d = 0u; d < LIGHT_TREE_MAX_DEPTH && link.x != LIGHT_NODE_LEAF; d++) {
        float p0 = light_first_child(link, p, n);
        if (p0 < 0.0) return false;
        bool first = w.x < p0;
        node = first ? link.x : link.y & ~LIGHT_NODE_TWO_SIDED;
        float q = first ? p0 : 1.0 - p0;
        pr *= q;
        w.part *= q;
        w.x = min(first ? w.x / p0 : (w.x - p0) / (1.0 - p0), 0.99999994);
        if (!w.fresh && w.part < LIGHT_FRESH_NUMBER_BELOW) {
            w.x = w.y;
            w.fresh = true;
        }
        link = light_node_link(node);
    }
    if (link.x != LIGHT_NODE_LEAF) return false;
    entry = node - 1u;
    prob = pr;
    return true;
}

// The probability tree_descend from `root` returns table entry `entry` at (p, n): the same products along the
// leaf's trail.
float tree_pmf_below(uint root, uint entry, vec3 p, vec3 n) {
    uint node = root;
    uvec4 leaf = light_node_link(entry + 1u);
    if (node == 0u || leaf.x != LIGHT_NODE_LEAF) return 0.0;
    float pr = 1.0;
    uvec4 link = light_node_link(node);
    for (uint d = 0u; d < LIGHT_TREE_MAX_DEPTH && link.x != LIGHT_NODE_LEAF; d++) {
        float p0 = light_first_child(link, p, n);
        if (p0 < 0.0) return 0.0;
        bool second = (((d < 32u ? leaf.z >> d : leaf.w >> (d - 32u))) & 1u) != 0u;
        node = second ? link.y & ~LIGHT_NODE_TWO_SIDED : link.x;
        pr *= second ? 1.0 - p0 : p0;
        link = light_node_link(node);
    }
    return node == entry + 1u ? pr : 0.0;
}

// From the tree's root.
float tree_pmf(uint entry, vec3 p, vec3 n) { return tree_pmf_below(light_node_link(0u).x, entry, p, n); }

// A receiver's normal in one float for the path state: octahedral, 12 bits a coordinate, as an integer below 2^24
// so the float is exact through any load or texel fetch. Light selection and its pdf twin both use the decoded one.
const float LIGHT_NORMAL_NONE = -1.0;
float pack_light_normal(vec3 n) {
    n /= max(abs(n.x) + abs(n.y) + abs(n.z), 1e-30);
    vec2 o = n.z >= 0.0 ? n.xy : (1.0 - abs(n.yx)) * vec2(n.x >= 0.0 ? 1.0 : -1.0, n.y >= 0.0 ? 1.0 : -1.0);
    uvec2 q = uvec2(clamp(round((o * 0.5 + 0.5) * 4095.0), 0.0, 4095.0));
    return float(q.x | (q.y << 12u));
}
vec3 unpack_light_normal(float f) {
    // A point in a medium has no normal: it packs as LIGHT_NORMAL_NONE, -1.
    if (f < 0.0) return vec3(0.0);
    uint b = uint(f);
    vec2 o = vec2(b & 4095u, b >> 12u) * (2.0 / 4095.0) - 1.0;
    vec3 n = vec3(o, 1.0 - abs(o.x) - abs(o.y));
    if (n.z < 0.0) n.xy = (1.0 - abs(n.yx)) * vec2(n.x >= 0.0 ? 1.0 : -1.0, n.y >= 0.0 ? 1.0 : -1.0);
    return normalize(n);
}

#endif
