# Convenience aliases for the scripts the README names.
.PHONY: demo test lab bench
demo: ; bash scripts/demo.sh
test: ; bash scripts/test.sh
lab:  ; bash scripts/lab.sh
bench: ; bash scripts/bench.sh
