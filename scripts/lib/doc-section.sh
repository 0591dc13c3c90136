# scripts/lib/doc-section.sh: how a benchmark script writes its section of
# a document (sourced, not run).
#   doc_section DOC "## Title" < body
# replaces the section that starts with the line "## Title" (up to the next
# "## " heading) with the title, a blank line, the body and a blank line, or
# appends it when the document has no such section; creates the document
# (with the benchmarks' header) when it does not exist. Written through a
# temporary file in the same folder and renamed: a reader never sees half.
doc_section() {
  local doc=$1 title=$2 body tmp
  body=$(cat)
  mkdir -p "$(dirname "$doc")"
  [[ -f $doc ]] || printf '# Benchmarks\n\nMeasured figures, each section written by the script named in it.\n' >"$doc"
  tmp=$(mktemp "$doc.XXXXXX")
  BODY=$body awk -v title="$title" '
    BEGIN { body = ENVIRON["BODY"] }
    $0 == title { print title; print ""; print body; print ""; skip = 1; done = 1; next }
    skip && /^## / { skip = 0 }
    !skip { print }
    END { if (!done) { print ""; print title; print ""; print body } }
  ' "$doc" >"$tmp" && mv "$tmp" "$doc"
}
