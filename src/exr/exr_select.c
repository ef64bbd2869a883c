/* fogpipe: which channels of an EXR frame are its colour and its depth
 * (src/exr/exr_internal.h): found by name (--color-layer, --depth-channel,
 * else R,G,B,A, Z, depth.Z, <layer>.Combined, <layer>.Depth.Z), in one
 * part or across parts, with one error line naming what was looked for. */
#include "exr_internal.h"
#include "fp.h"

#include <stdio.h>
#include <string.h>

/* Find a channel by exact name, in part `prefer` first, then in the
 * others in file order. */
static int find_channel(const fp_frame_t *f, const char *name, int prefer,
                        int *part, int *chan)
{
    for (int k = -1; k < f->num_parts; ++k) {
        int p = k < 0 ? prefer : k;
        if (p < 0 || (k >= 0 && p == prefer))
            continue;
        const fp_part_t *pt = &f->parts[p];
        for (int c = 0; c < pt->num_chans; ++c)
            if (strcmp(pt->chans[c].name, name) == 0) {
                *part = p;
                *chan = c;
                return 1;
            }
    }
    return 0;
}

int fp_exr_find_in_part(const fp_part_t *pt, const char *name)
{
    for (int c = 0; c < pt->num_chans; ++c)
        if (strcmp(pt->chans[c].name, name) == 0)
            return c;
    return -1;
}

/* Colour is prefix+R, G, B (and optional A) in one part. */
static int try_color(fp_frame_t *f, const char *prefix, int only_part)
{
    static const char *const comp[4] = { "R", "G", "B", "A" };
    char names[4][300];
    for (int i = 0; i < 4; ++i)
        snprintf(names[i], sizeof names[i], "%s%s", prefix, comp[i]);
    for (int p = 0; p < f->num_parts; ++p) {
        if (only_part >= 0 && p != only_part)
            continue;
        int idx[4];
        for (int i = 0; i < 4; ++i)
            idx[i] = fp_exr_find_in_part(&f->parts[p], names[i]);
        if (idx[0] < 0 || idx[1] < 0 || idx[2] < 0)
            continue;
        f->color_part = p;
        for (int i = 0; i < 4; ++i)
            f->color_chan[i] = idx[i];
        return 1;
    }
    return 0;
}

/* Locate colour and depth by name (see fp_exr_select_t).  `layer` gets
 * the view layer of the colour, whose depth is preferred. */
int fp_exr_select_channels(fp_frame_t *f, const fp_exr_select_t *sel,
                           const char *where, long frame)
{
    char layer[300] = "";
    char prefix[300];
    const char *cl = sel && sel->color_layer ? sel->color_layer : "";
    const char *dc = sel && sel->depth_channel ? sel->depth_channel : "";
    int need_color = sel ? sel->need_color : 1;
    int need_depth = sel ? sel->need_depth : 1;

    f->color_part = f->depth_part = -1;
    f->color_chan[0] = f->color_chan[1] = f->color_chan[2] = -1;
    f->color_chan[3] = f->depth_chan = -1;

    if (*cl) {
        snprintf(prefix, sizeof prefix, "%s.", cl);
        if (try_color(f, prefix, -1)) {
            snprintf(layer, sizeof layer, "%s", cl);
        } else {
            /* "--color-layer ViewLayer" means ViewLayer.Combined.* too */
            snprintf(prefix, sizeof prefix, "%s.Combined.", cl);
            if (try_color(f, prefix, -1))
                snprintf(layer, sizeof layer, "%s", cl);
        }
        if (f->color_part < 0 && need_color)
            return fp_error("%s: frame %ld: no color channels %s.R, %s.G, %s.B "
                            "(from --color-layer)", where, frame, cl, cl, cl);
    } else if (!try_color(f, "", -1)) {
        /* Blender multilayer: <layer>.Combined.R, the first such layer */
        static const char suffix[] = ".Combined.R";
        size_t sl = sizeof suffix - 1;
        for (int p = 0; p < f->num_parts && f->color_part < 0; ++p) {
            const fp_part_t *pt = &f->parts[p];
            for (int c = 0; c < pt->num_chans && f->color_part < 0; ++c) {
                const char *n = pt->chans[c].name;
                size_t len = strlen(n);
                if (len <= sl || len - sl >= sizeof layer ||
                    strcmp(n + len - sl, suffix) != 0)
                    continue;
                snprintf(prefix, sizeof prefix, "%.*s.Combined.",
                         (int) (len - sl), n);
                if (try_color(f, prefix, p))
                    snprintf(layer, sizeof layer, "%.*s", (int) (len - sl), n);
            }
        }
        if (f->color_part < 0 && need_color)
            return fp_error("%s: frame %ld: no color channels (looked for R,G,B "
                            "and *.Combined.R,G,B; use --color-layer)",
                            where, frame);
    }
    if (f->color_part >= 0) {
        /* "<layer>.Combined" given as the layer: its view layer is <layer> */
        size_t ll = strlen(layer);
        if (ll > 9 && strcmp(layer + ll - 9, ".Combined") == 0)
            layer[ll - 9] = '\0';
    }

    if (*dc) {
        if (!find_channel(f, dc, f->color_part, &f->depth_part, &f->depth_chan)
            && need_depth)
            return fp_error("%s: frame %ld: no depth channel '%s' "
                            "(from --depth-channel)", where, frame, dc);
    } else {
        char cand[4][320];
        int nc = 0;
        if (layer[0]) {
            snprintf(cand[nc++], sizeof cand[0], "%s.Depth.Z", layer);
            snprintf(cand[nc++], sizeof cand[0], "%s.Z", layer);
        }
        snprintf(cand[nc++], sizeof cand[0], "Z");
        snprintf(cand[nc++], sizeof cand[0], "depth.Z");
        for (int i = 0; i < nc && f->depth_part < 0; ++i)
            find_channel(f, cand[i], f->color_part, &f->depth_part,
                         &f->depth_chan);
        /* any view layer's depth, the colour's part first */
        static const char suffix[] = ".Depth.Z";
        size_t sl = sizeof suffix - 1;
        for (int k = -1; k < f->num_parts && f->depth_part < 0; ++k) {
            int p = k < 0 ? f->color_part : k;
            if (p < 0 || (k >= 0 && p == f->color_part))
                continue;
            const fp_part_t *pt = &f->parts[p];
            for (int c = 0; c < pt->num_chans; ++c) {
                const char *n = pt->chans[c].name;
                size_t len = strlen(n);
                if (len > sl && strcmp(n + len - sl, suffix) == 0) {
                    f->depth_part = p;
                    f->depth_chan = c;
                    break;
                }
            }
        }
        if (f->depth_part < 0 && need_depth)
            return fp_error("%s: frame %ld: no depth channel (looked for Z, "
                            "depth.Z, *.Depth.Z; use --depth-channel)",
                            where, frame);
    }

    /* Colour and depth must be full resolution and cover the same pixels.
     * What is not needed (depth from a --depth sequence, say) is dropped
     * instead: it still passes through as an ordinary channel. */
    for (int i = 0; i < 5; ++i) {
        int p = i < 4 ? f->color_part : f->depth_part;
        int c = i < 4 ? f->color_chan[i] : f->depth_chan;
        if (p < 0 || c < 0)
            continue;
        const fp_chan_t *ch = &f->parts[p].chans[c];
        if (ch->xs == 1 && ch->ys == 1)
            continue;
        if (i < 4 ? need_color : need_depth)
            return fp_error("%s: frame %ld: channel %s is sub-sampled (%dx%d); "
                            "color and depth must be full resolution",
                            where, frame, ch->name, ch->xs, ch->ys);
        if (i < 4)
            f->color_part = -1;
        else
            f->depth_part = -1;
    }
    if (f->color_part >= 0 && f->depth_part >= 0 &&
        f->color_part != f->depth_part) {
        const exr_attr_box2i_t *a = &f->parts[f->color_part].dw;
        const exr_attr_box2i_t *b = &f->parts[f->depth_part].dw;
        if (memcmp(a, b, sizeof *a) != 0) {
            if (need_depth)
                return fp_error("%s: frame %ld: color (part %d, %dx%d at %d,%d) "
                                "and depth (part %d, %dx%d at %d,%d) have "
                                "different data windows", where, frame,
                                f->color_part, a->max.x - a->min.x + 1,
                                a->max.y - a->min.y + 1, a->min.x, a->min.y,
                                f->depth_part, b->max.x - b->min.x + 1,
                                b->max.y - b->min.y + 1, b->min.x, b->min.y);
            f->depth_part = -1;
        }
    }
    if (f->color_part < 0)
        f->color_chan[0] = f->color_chan[1] = f->color_chan[2] = f->color_chan[3] = -1;
    if (f->depth_part < 0)
        f->depth_chan = -1;
    return FP_OK;
}
