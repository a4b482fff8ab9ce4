#!/usr/bin/env python3
"""Writes cornell.gltf: the Cornell box as Cornell's Program of Computer Graphics publishes it
(www.graphics.cornell.edu/online/box/data.html: vertices in millimetres, written here in
metres), with its camera (at (278, 273, -800) mm looking along +z, a 35 mm lens on a 25 mm
film: a vertical field of view of 2·atan(12.5 / 35) = 39.3°).

The published reflectances and the lamp's emission are spectra; the RGB values used for them
are the ones renderer test suites commonly take (white 0.725 0.71 0.68, red 0.63 0.065 0.05,
green 0.14 0.45 0.091, lamp radiance 17 12 4 W/m²/sr). The published lamp lies in the
ceiling's plane; here it is 1 mm below it, as lamps set into ceilings are (a coplanar lamp
leaves the ceiling under it undefined for any renderer). Each quad is wound to face the
inside of the box (walls) or away from its block's centre (blocks). Run it from any folder; it
writes next to itself.
"""
import math
import os

from gltf_doc import GltfDoc

MM = 0.001
ROOM_CENTRE = (278.0, 274.4, 279.6)

floor = [[(552.8, 0, 0), (0, 0, 0), (0, 0, 559.2), (549.6, 0, 559.2)]]
ceiling = [[(556, 548.8, 0), (556, 548.8, 559.2), (0, 548.8, 559.2), (0, 548.8, 0)]]
back = [[(549.6, 0, 559.2), (0, 0, 559.2), (0, 548.8, 559.2), (556, 548.8, 559.2)]]
green = [[(0, 0, 559.2), (0, 0, 0), (0, 548.8, 0), (0, 548.8, 559.2)]]
red = [[(552.8, 0, 0), (549.6, 0, 559.2), (556, 548.8, 559.2), (556, 548.8, 0)]]
light = [[(343, 547.8, 227), (343, 547.8, 332), (213, 547.8, 332), (213, 547.8, 227)]]
short_block = [
    [(130, 165, 65), (82, 165, 225), (240, 165, 272), (290, 165, 114)],
    [(290, 0, 114), (290, 165, 114), (240, 165, 272), (240, 0, 272)],
    [(130, 0, 65), (130, 165, 65), (290, 165, 114), (290, 0, 114)],
    [(82, 0, 225), (82, 165, 225), (130, 165, 65), (130, 0, 65)],
    [(240, 0, 272), (240, 165, 272), (82, 165, 225), (82, 0, 225)],
]
tall_block = [
    [(423, 330, 247), (265, 330, 296), (314, 330, 456), (472, 330, 406)],
    [(423, 0, 247), (423, 330, 247), (472, 330, 406), (472, 0, 406)],
    [(472, 0, 406), (472, 330, 406), (314, 330, 456), (314, 0, 456)],
    [(314, 0, 456), (314, 330, 456), (265, 330, 296), (265, 0, 296)],
    [(265, 0, 296), (265, 330, 296), (423, 330, 247), (423, 0, 247)],
]


def centre(quads):
    points = [p for q in quads for p in q]
    return tuple(sum(p[i] for p in points) / len(points) for i in range(3))


def normal(q):
    n = [0.0, 0.0, 0.0]
    for i in range(4):
        a, b = q[i], q[(i + 1) % 4]
        n[0] += (a[1] - b[1]) * (a[2] + b[2])
        n[1] += (a[2] - b[2]) * (a[0] + b[0])
        n[2] += (a[0] - b[0]) * (a[1] + b[1])
    return n


def facing(quads, towards, inward):
    """Winds each quad so that its normal points at `towards` (inward) or away from it."""
    out = []
    for q in quads:
        c = centre([q])
        d = [towards[i] - c[i] for i in range(3)]
        dot = sum(normal(q)[i] * d[i] for i in range(3))
        out.append(list(q) if (dot > 0) == inward else list(reversed(q)))
    return out


g = GltfDoc("penumbra scenes/gltf/make_cornell.py", "Cornell box",
            ["KHR_materials_emissive_strength"])


def material(name, colour, emissive=None, strength=None):
    return g.material(name, colour, 1.0, emissive, strength)


def add_object(name, quads, mat):
    mesh = g.mesh(name, [[tuple(c * MM for c in p) for p in q] for q in quads], mat)
    g.doc["scenes"][0]["nodes"].append(g.node(name=name, mesh=mesh))


white = material("white", [0.725, 0.71, 0.68])
red_mat = material("red", [0.63, 0.065, 0.05])
green_mat = material("green", [0.14, 0.45, 0.091])
lamp = material("light", [0.78, 0.78, 0.78], [1.0, 12 / 17, 4 / 17], 17.0)

add_object("floor", facing(floor, ROOM_CENTRE, True), white)
add_object("ceiling", facing(ceiling, ROOM_CENTRE, True), white)
add_object("back", facing(back, ROOM_CENTRE, True), white)
add_object("red-wall", facing(red, ROOM_CENTRE, True), red_mat)
add_object("green-wall", facing(green, ROOM_CENTRE, True), green_mat)
add_object("light", facing(light, (278, 0, 279.5), True), lamp)
add_object("short-block", facing(short_block, centre(short_block), False), white)
add_object("tall-block", facing(tall_block, centre(tall_block), False), white)

# The camera looks along -z in glTF: turned 180 degrees about +y to look along +z.
g.doc["cameras"].append({"name": "default", "type": "perspective",
                         "perspective": {"yfov": 2 * math.atan(12.5 / 35), "znear": 0.01,
                                         "aspectRatio": 1.0}})
g.doc["scenes"][0]["nodes"].append(g.node(name="default", camera=0,
                                          translation=[0.278, 0.273, -0.8],
                                          rotation=[0.0, 1.0, 0.0, 0.0]))
g.write(os.path.join(os.path.dirname(os.path.abspath(__file__)), "cornell.gltf"))
