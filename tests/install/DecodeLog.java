// Reads a clutterseg LCM log with LCM's Java library and the installed bindings jar, decodes
// every objects_t and label_image_t (labels through LabelImageCodec), checks that each label
// image's largest id is its frame's object count, and prints
//   java: <frames> frames, <objects> objects, <label images> label images ok
import clutterseg.LabelImageCodec;
import clutterseg.label_image_t;
import clutterseg.objects_t;
import java.io.EOFException;
import java.util.HashMap;
import java.util.Map;
import lcm.logging.Log;

public class DecodeLog {
  public static void main(String[] args) throws Exception {
    Log log = new Log(args[0], "r");
    Map<Long, Integer> objectsPerFrame = new HashMap<>();
    Map<Long, Integer> maxLabelPerFrame = new HashMap<>();
    int frames = 0;
    long objects = 0;
    try {
      while (true) {
        Log.Event ev = log.readNext();
        if (ev.channel.equals("CLUTTERSEG_OBJECTS")) {
          objects_t m = new objects_t(ev.data);
          objectsPerFrame.put(m.frame_seq, m.num_objects);
          objects += m.num_objects;
          ++frames;
        } else if (ev.channel.equals("CLUTTERSEG_LABELS")) {
          label_image_t m = new label_image_t(ev.data);
          int max = 0;
          for (int id : LabelImageCodec.decode(m)) max = Math.max(max, id);
          maxLabelPerFrame.put(m.frame_seq, max);
        }
      }
    } catch (EOFException end) {
      // end of log
    }
    for (Map.Entry<Long, Integer> e : maxLabelPerFrame.entrySet()) {
      Integer n = objectsPerFrame.get(e.getKey());
      if (n == null || !n.equals(e.getValue())) {
        System.out.println("java: frame " + e.getKey() + ": label image max " + e.getValue()
            + " but " + n + " objects");
        System.exit(1);
      }
    }
    System.out.println("java: " + frames + " frames, " + objects + " objects, "
        + maxLabelPerFrame.size() + " label images ok");
    System.exit(frames > 0 && objects > 0 ? 0 : 1);
  }
}
