#!/usr/bin/env python3
"""Writes scenes/assets/calcite-page.png, the backlit stencil of scenes/calcite.xml:
256x256 grey, black with the word SNELL (a 5x7 font scaled 4x) and a thin vertical line
(texel columns 56-57, the world x = -0.555 of the scene's page; it ends 0.08 inside the slab) for measuring the walk-off.
Standard library only."""
import struct
import zlib

W = H = 256
FONT = {
    "S": ["01111", "10000", "10000", "01110", "00001", "00001", "11110"],
    "N": ["10001", "11001", "10101", "10011", "10001", "10001", "10001"],
    "E": ["11111", "10000", "10000", "11110", "10000", "10000", "11111"],
    "L": ["10000", "10000", "10000", "10000", "10000", "10000", "11111"],
}


def main():
    img = [[0] * W for _ in range(H)]
    for i, ch in enumerate("SNELL"):
        for r, bits in enumerate(FONT[ch]):
            for c, bit in enumerate(bits):
                if bit == "1":
                    for dr in range(4):
                        for dc in range(4):
                            img[36 + 4 * r + dr][84 + 24 * i + 4 * c + dc] = 255
    for r in range(130, 226):
        img[r][56] = img[r][57] = 255
    img = img[::-1]  # the rectangle's v runs up the page
    raw = b"".join(b"\x00" + bytes(row) for row in img)

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", W, H, 8, 0, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
    with open("scenes/assets/calcite-page.png", "wb") as f:
        f.write(png)


if __name__ == "__main__":
    main()
