// Headless check that lcm-spy's class-path scan finds every vloc type:
// for each class named on the command line, read its LCM fingerprint and
// ask lcm.spy.LCMTypeDatabase (what lcm-spy uses to decode) for it.
// Exit status 0 when every type is found; prints one line per missing type.
public class SpyTypeCheck {
  public static void main(String[] args) throws Exception {
    lcm.spy.LCMTypeDatabase db = new lcm.spy.LCMTypeDatabase();
    int missing = 0;
    for (String name : args) {
      Class<?> cls = Class.forName(name);
      long fingerprint = cls.getField("LCM_FINGERPRINT").getLong(null);
      Class<?> found = db.getClassByFingerprint(fingerprint);
      if (found == null || !found.getName().equals(name)) {
        System.out.println("MISSING " + name);
        missing++;
      } else {
        System.out.println("found " + name);
      }
    }
    System.out.println(missing == 0 ? "all " + args.length + " vloc types visible to lcm-spy"
                                    : missing + " vloc types NOT visible to lcm-spy");
    System.exit(missing == 0 ? 0 : 1);
  }
}
