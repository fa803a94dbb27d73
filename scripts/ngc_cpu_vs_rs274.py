import resource, subprocess, sys
def cpu(cmd, stdin=None, n=5):
    out=[]
    for _ in range(n):
        r0=resource.getrusage(resource.RUSAGE_CHILDREN)
        subprocess.run(cmd, input=stdin, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
        r1=resource.getrusage(resource.RUSAGE_CHILDREN)
        out.append((r1.ru_utime-r0.ru_utime)+(r1.ru_stime-r0.ru_stime))
    out.sort(); return out[len(out)//2]
f=sys.argv[1]; ncd=sys.argv[2]
a=cpu(["rs274","-g",f,"/dev/null"], stdin=b"\n\n\n")
b=cpu([ncd,"check",f])
print("rs274 median CPU %.3f s, ncd check median CPU %.3f s, ratio %.2f" % (a,b,b/a))
c=cpu([ncd,"check","--summary",f])
print("ncd check --summary median CPU %.3f s, ratio %.2f" % (c,c/a))
