package clutterseg;

import java.util.zip.DataFormatException;
import java.util.zip.Inflater;

/**
 * Decodes the payload of a {@link label_image_t}: the per-pixel object ids of one frame,
 * row-major (pixel (u, v) at index v * width + u), 0 = background or no measurement. Handles
 * the three layouts of label_image_t.compression: COMPRESSION_NONE (little-endian uint16 per
 * pixel), COMPRESSION_RLE ((uint16 id, uint32 run length) little-endian pairs) and
 * COMPRESSION_ZLIB (the uncompressed layout deflated with zlib). A malformed message throws
 * IllegalArgumentException before anything is allocated for it. Thread-safe (stateless).
 */
public final class LabelImageCodec {
  /** The daemon's frame limit: larger images are refused. */
  public static final int MAX_PIXELS = 4096 * 4096;

  private LabelImageCodec() {}

  /** The ids of `msg`, width * height entries in 0..65535. */
  public static int[] decode(label_image_t msg) {
    if (msg.width < 0 || msg.height < 0 || (long) msg.width * msg.height > MAX_PIXELS) {
      throw new IllegalArgumentException("label_image_t: bad size " + msg.width + "x" + msg.height);
    }
    final int n = msg.width * msg.height;
    final byte[] data = msg.data;
    if (data == null || msg.size != data.length) {
      throw new IllegalArgumentException("label_image_t: size field does not match the data");
    }
    switch (msg.compression) {
      case label_image_t.COMPRESSION_NONE:
        return fromLe16(data, data.length, n);
      case label_image_t.COMPRESSION_ZLIB: {
        final byte[] raw = new byte[2 * n];
        final Inflater inflater = new Inflater();
        try {
          inflater.setInput(data);
          final int got = inflater.inflate(raw);
          if (!inflater.finished()) {
            throw new IllegalArgumentException("label_image_t: zlib data larger than the image");
          }
          return fromLe16(raw, got, n);
        } catch (DataFormatException e) {
          throw new IllegalArgumentException("label_image_t: bad zlib data: " + e.getMessage());
        } finally {
          inflater.end();
        }
      }
      case label_image_t.COMPRESSION_RLE: {
        if (data.length % 6 != 0) {
          throw new IllegalArgumentException("label_image_t: RLE data is truncated");
        }
        final int[] labels = new int[n];
        long pos = 0;
        for (int i = 0; i < data.length; i += 6) {
          final int label = (data[i] & 0xff) | ((data[i + 1] & 0xff) << 8);
          final long run = (data[i + 2] & 0xffL) | ((data[i + 3] & 0xffL) << 8)
              | ((data[i + 4] & 0xffL) << 16) | ((data[i + 5] & 0xffL) << 24);
          if (run > n - pos) {
            throw new IllegalArgumentException("label_image_t: RLE runs exceed the image");
          }
          java.util.Arrays.fill(labels, (int) pos, (int) (pos + run), label);
          pos += run;
        }
        if (pos != n) {
          throw new IllegalArgumentException("label_image_t: RLE runs do not cover the image");
        }
        return labels;
      }
      default:
        throw new IllegalArgumentException("label_image_t: unknown compression " + msg.compression);
    }
  }

  private static int[] fromLe16(byte[] raw, int bytes, int n) {
    if (bytes != 2 * n) {
      throw new IllegalArgumentException(
          "label_image_t: " + bytes + " label bytes for " + n + " pixels");
    }
    final int[] labels = new int[n];
    for (int i = 0; i < n; ++i) labels[i] = (raw[2 * i] & 0xff) | ((raw[2 * i + 1] & 0xff) << 8);
    return labels;
  }
}
