!> Registry of the per-node and per-cell fields of one rank: each field has a name, a centre
!> (node or cell), a kind (real(wp) or integer(ip)) and a width (values per entity), and its
!> storage (width, entities) belongs to the registry. Packing, unpacking, reordering and
!> resizing work on every field at once, so checkpoint, output and migration are written once
!> against the registry instead of per array.
!>
!> Ownership: the registry owns the storage. A consumer fetches a pointer to a field's values
!> (real_data, int_data, real_flat, int_flat) after set-up (all fields added) and again after
!> every operation that reallocates (add, resize, reset, permute, and a migration); a pointer
!> fetched before is then undefined. The registry object must therefore be a TARGET (or a
!> component of one). Node fields span all local nodes (owned first, then halo); cell fields
!> span the local cells, in the local lattice's order.
!>
!> Borrowed fields (borrow_real, borrow_int): the values are the caller's array, which the
!> registry reads and writes in place without a copy (a checkpoint's records packed from, and
!> read into, the run's own arrays). The caller keeps the array allocated, unmoved and of
!> its size while the registry holds it; operations that reallocate a centre with a borrowed
!> field (resize, reset, permute) refuse (stat 4). Zero fields (add_zeros): zeros in every
!> record, no storage, what is unpacked into them dropped. owns(id) tells which fields hold
!> their values in the registry.
!>
!> Record layout: one entity's record is its fields' values in registration order (fields of
!> the other centre skipped), each as width values of bytes_real or bytes_int bytes, packed
!> without padding; layout() lists each field's byte offset and size in the record.
module iem_fields
  use, intrinsic :: iso_fortran_env, only: int8
  use iem_kinds, only: wp, ip, i8
  implicit none
  private
  public :: field_registry_t, field_slot_t
  public :: centre_node, centre_cell, kind_real, kind_int, bytes_real, bytes_int

  !> Centres: a field has one value set per local node or per local cell.
  integer, parameter :: centre_node = 1, centre_cell = 2
  !> Kinds of values: real(wp) or integer(ip).
  integer, parameter :: kind_real = 1, kind_int = 2
  !> Bytes of one value of each kind in a record.
  integer, parameter :: bytes_real = storage_size(1.0_wp)/8, bytes_int = storage_size(1_ip)/8

  !> One field and its storage (width, entities): r for reals, i for integers, or, borrowed,
  !> the caller's values rb, ib, or none (zeros).
  type :: field_t
    character(len=:), allocatable :: name
    integer :: centre = 0, kind = 0, width = 0
    real(wp), allocatable :: r(:, :)
    integer(ip), allocatable :: i(:, :)
    logical :: borrowed = .false., zeros = .false.
    real(wp), pointer, contiguous :: rb(:, :) => null()
    integer(ip), pointer, contiguous :: ib(:, :) => null()
  end type field_t

  !> Place of one field in the per-entity record: name, kind, width, byte offset (0-based)
  !> and size in bytes.
  type :: field_slot_t
    character(len=:), allocatable :: name
    integer :: kind = 0, width = 0, offset = 0, bytes = 0
  end type field_slot_t

  !> The fields of one rank and the number of entities (nodes, cells) they span.
  type :: field_registry_t
    integer :: n_fields = 0
    !> Entities of each centre: local nodes (owned + halo) and local cells.
    integer :: n_entities(2) = 0
    type(field_t), allocatable :: f(:)
  contains
    procedure :: init => registry_init
    procedure :: free => registry_free
    procedure :: add => registry_add
    procedure :: borrow_real => registry_borrow_real
    procedure :: borrow_int => registry_borrow_int
    procedure :: add_zeros => registry_add_zeros
    procedure :: owns => registry_owns
    procedure :: find => registry_find
    procedure :: name => registry_name
    procedure :: centre => registry_centre
    procedure :: kind => registry_kind
    procedure :: width => registry_width
    procedure :: n_of => registry_n_of
    procedure :: has_centre => registry_has_centre
    procedure :: real_data => registry_real_data
    procedure :: int_data => registry_int_data
    procedure :: real_flat => registry_real_flat
    procedure :: int_flat => registry_int_flat
    procedure :: record_bytes => registry_record_bytes
    procedure :: layout => registry_layout
    procedure :: resize => registry_resize
    procedure :: reset => registry_reset
    procedure :: permute => registry_permute
    procedure :: pack_one => registry_pack_one
    procedure :: unpack_one => registry_unpack_one
    procedure :: pack => registry_pack
    procedure :: unpack => registry_unpack
  end type field_registry_t

contains

  !> Start an empty registry for n_nodes local nodes and n_cells local cells.
  subroutine registry_init(this, n_nodes, n_cells)
    class(field_registry_t), intent(inout) :: this
    integer, intent(in) :: n_nodes, n_cells
    call this%free()
    this%n_entities = [n_nodes, n_cells]
    allocate(this%f(0))
  end subroutine registry_init

  !> Release every field.
  subroutine registry_free(this)
    class(field_registry_t), intent(inout) :: this
    if (allocated(this%f)) deallocate(this%f)
    this%n_fields = 0
    this%n_entities = 0
  end subroutine registry_free

  !> Add a field (zero-filled) and return its id (1, 2, ... in registration order). stat: 0
  !> done; 1 the name is taken; 2 a bad centre, kind or width (< 1); 3 out of memory. id = 0
  !> when stat /= 0. Pointers fetched before are undefined afterwards.
  subroutine registry_add(this, name, centre, kind, width, id, stat)
    class(field_registry_t), intent(inout) :: this
    character(len=*), intent(in) :: name
    integer, intent(in) :: centre, kind, width
    integer, intent(out) :: id, stat
    type(field_t), allocatable :: kept(:)
    integer :: ierr, n
    call add_entry(this, name, centre, kind, width, -1_i8, id, stat)
    if (stat /= 0) return
    n = this%n_entities(centre)
    associate(fk => this%f(id))
      if (kind == kind_real) then
        allocate(fk%r(width, n), stat=ierr)
        if (ierr == 0) fk%r = 0.0_wp
      else
        allocate(fk%i(width, n), stat=ierr)
        if (ierr == 0) fk%i = 0_ip
      end if
    end associate
    if (ierr /= 0) then
      ! keep the registry as it was
      call move_fields(this%f, kept, id - 1, 0)
      call move_alloc(kept, this%f)
      this%n_fields = id - 1
      id = 0
      stat = 3
    end if
  end subroutine registry_add

  !> Add a real field whose values are the caller's array a (width values of each entity, one
  !> entity after the other: exactly width times the centre's entities), read and written in
  !> place, not copied; id and stat as add's (stat 2 also when a has another size).
  subroutine registry_borrow_real(this, name, centre, width, a, id, stat)
    class(field_registry_t), intent(inout) :: this
    character(len=*), intent(in) :: name
    integer, intent(in) :: centre, width
    real(wp), intent(inout), target, contiguous :: a(:)
    integer, intent(out) :: id, stat
    call add_entry(this, name, centre, kind_real, width, size(a, kind=i8), id, stat)
    if (stat /= 0) return
    this%f(id)%borrowed = .true.
    this%f(id)%rb(1:width, 1:this%n_entities(centre)) => a
  end subroutine registry_borrow_real

  !> borrow_real for an integer field.
  subroutine registry_borrow_int(this, name, centre, width, a, id, stat)
    class(field_registry_t), intent(inout) :: this
    character(len=*), intent(in) :: name
    integer, intent(in) :: centre, width
    integer(ip), intent(inout), target, contiguous :: a(:)
    integer, intent(out) :: id, stat
    call add_entry(this, name, centre, kind_int, width, size(a, kind=i8), id, stat)
    if (stat /= 0) return
    this%f(id)%borrowed = .true.
    this%f(id)%ib(1:width, 1:this%n_entities(centre)) => a
  end subroutine registry_borrow_int

  !> Add a field of zeros (kind_real or kind_int): zeros in every record, no storage (what is
  !> unpacked into it is dropped; it has no data to fetch); id and stat as add's.
  subroutine registry_add_zeros(this, name, centre, kind, width, id, stat)
    class(field_registry_t), intent(inout) :: this
    character(len=*), intent(in) :: name
    integer, intent(in) :: centre, kind, width
    integer, intent(out) :: id, stat
    call add_entry(this, name, centre, kind, width, -1_i8, id, stat)
    if (stat == 0) this%f(id)%zeros = .true.
  end subroutine registry_add_zeros

  !> Whether the registry holds field id's values (not a borrowed or a zero field).
  pure logical function registry_owns(this, id) result(owns)
    class(field_registry_t), intent(in) :: this
    integer, intent(in) :: id
    owns = .not. (this%f(id)%borrowed .or. this%f(id)%zeros)
  end function registry_owns

  !> The checks and the entry, without storage, of a field of n values (n < 0: not checked).
  subroutine add_entry(this, name, centre, kind, width, n, id, stat)
    type(field_registry_t), intent(inout) :: this
    character(len=*), intent(in) :: name
    integer, intent(in) :: centre, kind, width
    integer(i8), intent(in) :: n
    integer, intent(out) :: id, stat
    type(field_t), allocatable :: grown(:)
    integer :: k
    id = 0
    stat = 0
    if (.not. allocated(this%f)) allocate(this%f(0))
    if (this%find(name) /= 0) then
      stat = 1
      return
    end if
    if ((centre /= centre_node .and. centre /= centre_cell) .or. width < 1 .or. &
        (kind /= kind_real .and. kind /= kind_int)) then
      stat = 2
      return
    end if
    if (n >= 0 .and. n /= int(width, i8)*this%n_entities(centre)) then
      stat = 2
      return
    end if
    call move_fields(this%f, grown, this%n_fields, 1)
    k = this%n_fields + 1
    grown(k)%name = name
    grown(k)%centre = centre
    grown(k)%kind = kind
    grown(k)%width = width
    call move_alloc(grown, this%f)
    this%n_fields = k
    id = k
  end subroutine add_entry

  !> Id of the field called name, 0 if none.
  pure integer function registry_find(this, name) result(id)
    class(field_registry_t), intent(in) :: this
    character(len=*), intent(in) :: name
    integer :: k
    id = 0
    do k = 1, this%n_fields
      if (this%f(k)%name == name) then
        id = k
        return
      end if
    end do
  end function registry_find

  !> Name of field id.
  pure function registry_name(this, id) result(name)
    class(field_registry_t), intent(in) :: this
    integer, intent(in) :: id
    character(len=:), allocatable :: name
    name = this%f(id)%name
  end function registry_name

  !> Centre of field id (centre_node or centre_cell).
  pure integer function registry_centre(this, id) result(centre)
    class(field_registry_t), intent(in) :: this
    integer, intent(in) :: id
    centre = this%f(id)%centre
  end function registry_centre

  !> Kind of field id (kind_real or kind_int).
  pure integer function registry_kind(this, id) result(kind)
    class(field_registry_t), intent(in) :: this
    integer, intent(in) :: id
    kind = this%f(id)%kind
  end function registry_kind

  !> Values per entity of field id.
  pure integer function registry_width(this, id) result(width)
    class(field_registry_t), intent(in) :: this
    integer, intent(in) :: id
    width = this%f(id)%width
  end function registry_width

  !> Number of entities of a centre.
  pure integer function registry_n_of(this, centre) result(n)
    class(field_registry_t), intent(in) :: this
    integer, intent(in) :: centre
    n = this%n_entities(centre)
  end function registry_n_of

  !> True when at least one field has this centre.
  pure logical function registry_has_centre(this, centre) result(has)
    class(field_registry_t), intent(in) :: this
    integer, intent(in) :: centre
    has = .false.
    if (this%n_fields > 0) has = any(this%f(1:this%n_fields)%centre == centre)
  end function registry_has_centre

  !> Pointer to the values (width, entities) of real field id; valid until the registry
  !> next reallocates.
  function registry_real_data(this, id) result(p)
    class(field_registry_t), intent(inout), target :: this
    integer, intent(in) :: id
    real(wp), pointer, contiguous :: p(:, :)
    if (this%f(id)%borrowed) then
      p => this%f(id)%rb
    else
      p => this%f(id)%r
    end if
  end function registry_real_data

  !> Pointer to the values (width, entities) of integer field id; valid until the registry
  !> next reallocates.
  function registry_int_data(this, id) result(p)
    class(field_registry_t), intent(inout), target :: this
    integer, intent(in) :: id
    integer(ip), pointer, contiguous :: p(:, :)
    if (this%f(id)%borrowed) then
      p => this%f(id)%ib
    else
      p => this%f(id)%i
    end if
  end function registry_int_data

  !> Rank-1 pointer to the values of real field id, entity after entity (width*entities);
  !> e.g. a field of width 12 on cells is the array over springs 12(c-1)+j.
  function registry_real_flat(this, id) result(p)
    class(field_registry_t), intent(inout), target :: this
    integer, intent(in) :: id
    real(wp), pointer, contiguous :: p(:), d(:, :)
    d => this%real_data(id)
    p(1:size(d)) => d
  end function registry_real_flat

  !> Rank-1 pointer to the values of integer field id, entity after entity.
  function registry_int_flat(this, id) result(p)
    class(field_registry_t), intent(inout), target :: this
    integer, intent(in) :: id
    integer(ip), pointer, contiguous :: p(:), d(:, :)
    d => this%int_data(id)
    p(1:size(d)) => d
  end function registry_int_flat

  !> Bytes of one entity's record of a centre (sum over its fields of width times value size).
  pure integer function registry_record_bytes(this, centre) result(nb)
    class(field_registry_t), intent(in) :: this
    integer, intent(in) :: centre
    integer :: k
    nb = 0
    do k = 1, this%n_fields
      if (this%f(k)%centre == centre) nb = nb + field_bytes(this%f(k))
    end do
  end function registry_record_bytes

  !> The record layout of a centre: one slot per field of that centre, in registration order.
  function registry_layout(this, centre) result(slots)
    class(field_registry_t), intent(in) :: this
    integer, intent(in) :: centre
    type(field_slot_t), allocatable :: slots(:)
    integer :: k, s, off
    allocate(slots(count(this%f(1:this%n_fields)%centre == centre)))
    s = 0
    off = 0
    do k = 1, this%n_fields
      if (this%f(k)%centre /= centre) cycle
      s = s + 1
      slots(s)%name = this%f(k)%name
      slots(s)%kind = this%f(k)%kind
      slots(s)%width = this%f(k)%width
      slots(s)%offset = off
      slots(s)%bytes = field_bytes(this%f(k))
      off = off + slots(s)%bytes
    end do
  end function registry_layout

  !> Change the number of entities of a centre to n, keeping the first min(n, old) entities'
  !> values and zeroing new ones. stat /= 0 when an allocation failed (fields already resized
  !> stay resized; the registry's count is then left unchanged); 4 when the centre has a
  !> borrowed field (nothing changed).
  subroutine registry_resize(this, centre, n, stat)
    class(field_registry_t), intent(inout) :: this
    integer, intent(in) :: centre, n
    integer, intent(out) :: stat
    integer, allocatable :: src(:)
    integer :: e
    allocate(src(n))
    do e = 1, n
      src(e) = merge(e, 0, e <= this%n_entities(centre))
    end do
    call this%permute(centre, src, stat)
  end subroutine registry_resize

  !> Reallocate every field of a centre for n entities, all zero (their old values dropped);
  !> stat 4 when the centre has a borrowed field (nothing changed).
  subroutine registry_reset(this, centre, n, stat)
    class(field_registry_t), intent(inout) :: this
    integer, intent(in) :: centre, n
    integer, intent(out) :: stat
    integer :: k, ierr
    stat = 0
    ierr = 0
    if (lends(this, centre)) then
      stat = 4
      return
    end if
    do k = 1, this%n_fields
      associate(fk => this%f(k))
        if (fk%centre /= centre .or. fk%zeros) cycle
        if (fk%kind == kind_real) then
          deallocate(fk%r)
          allocate(fk%r(fk%width, n), stat=ierr)
          if (ierr == 0) fk%r = 0.0_wp
        else
          deallocate(fk%i)
          allocate(fk%i(fk%width, n), stat=ierr)
          if (ierr == 0) fk%i = 0_ip
        end if
      end associate
      if (ierr /= 0) then
        stat = 1
        return
      end if
    end do
    this%n_entities(centre) = n
  end subroutine registry_reset

  !> Reorder (and resize) every field of a centre: new entity e takes the values of old
  !> entity src(e), or zeros where src(e) = 0; the centre then has size(src) entities.
  !> stat /= 0 when an allocation failed or src names an entity that does not exist; 4 when
  !> the centre has a borrowed field (nothing changed).
  subroutine registry_permute(this, centre, src, stat)
    class(field_registry_t), intent(inout) :: this
    integer, intent(in) :: centre
    integer, intent(in) :: src(:)
    integer, intent(out) :: stat
    real(wp), allocatable :: r(:, :)
    integer(ip), allocatable :: iv(:, :)
    integer :: k, e, n, ierr
    stat = 0
    ierr = 0
    if (lends(this, centre)) then
      stat = 4
      return
    end if
    if (any(src < 0 .or. src > this%n_entities(centre))) then
      stat = 2
      return
    end if
    n = size(src)
    do k = 1, this%n_fields
      associate(fk => this%f(k))
        if (fk%centre /= centre .or. fk%zeros) cycle
        if (fk%kind == kind_real) then
          allocate(r(fk%width, n), stat=ierr)
          if (ierr /= 0) exit
          do e = 1, n
            if (src(e) > 0) then
              r(:, e) = fk%r(:, src(e))
            else
              r(:, e) = 0.0_wp
            end if
          end do
          call move_alloc(r, fk%r)
        else
          allocate(iv(fk%width, n), stat=ierr)
          if (ierr /= 0) exit
          do e = 1, n
            if (src(e) > 0) then
              iv(:, e) = fk%i(:, src(e))
            else
              iv(:, e) = 0_ip
            end if
          end do
          call move_alloc(iv, fk%i)
        end if
      end associate
    end do
    if (ierr /= 0) then
      stat = 1
      return
    end if
    this%n_entities(centre) = n
  end subroutine registry_permute

  !> Copy entity e's record of a centre into rec(1:record_bytes(centre)).
  subroutine registry_pack_one(this, centre, e, rec)
    class(field_registry_t), intent(in) :: this
    integer, intent(in) :: centre, e
    integer(int8), intent(inout) :: rec(:)
    integer :: k, off, nb
    off = 0
    do k = 1, this%n_fields
      associate(fk => this%f(k))
        if (fk%centre /= centre) cycle
        nb = field_bytes(fk)
        if (fk%zeros) then
          rec(off + 1:off + nb) = 0_int8
        else if (fk%borrowed) then
          if (fk%kind == kind_real) then
            rec(off + 1:off + nb) = transfer(fk%rb(:, e), 0_int8, nb)
          else
            rec(off + 1:off + nb) = transfer(fk%ib(:, e), 0_int8, nb)
          end if
        else if (fk%kind == kind_real) then
          rec(off + 1:off + nb) = transfer(fk%r(:, e), 0_int8, nb)
        else
          rec(off + 1:off + nb) = transfer(fk%i(:, e), 0_int8, nb)
        end if
        off = off + nb
      end associate
    end do
  end subroutine registry_pack_one

  !> Set entity e's values of a centre from its record rec(1:record_bytes(centre)).
  subroutine registry_unpack_one(this, centre, e, rec)
    class(field_registry_t), intent(inout) :: this
    integer, intent(in) :: centre, e
    integer(int8), intent(in) :: rec(:)
    integer :: k, off, nb
    off = 0
    do k = 1, this%n_fields
      associate(fk => this%f(k))
        if (fk%centre /= centre) cycle
        nb = field_bytes(fk)
        if (fk%zeros) then
          ! (dropped)
        else if (fk%borrowed) then
          if (fk%kind == kind_real) then
            fk%rb(:, e) = transfer(rec(off + 1:off + nb), 1.0_wp, fk%width)
          else
            fk%ib(:, e) = transfer(rec(off + 1:off + nb), 1_ip, fk%width)
          end if
        else if (fk%kind == kind_real) then
          fk%r(:, e) = transfer(rec(off + 1:off + nb), 1.0_wp, fk%width)
        else
          fk%i(:, e) = transfer(rec(off + 1:off + nb), 1_ip, fk%width)
        end if
        off = off + nb
      end associate
    end do
  end subroutine registry_unpack_one

  !> Pack the records of the entities listed (of a centre), one after another, into buf
  !> (at least record_bytes(centre)*size(entities) bytes).
  subroutine registry_pack(this, centre, entities, buf)
    class(field_registry_t), intent(in) :: this
    integer, intent(in) :: centre, entities(:)
    integer(int8), intent(inout) :: buf(:)
    integer(i8) :: nb, off
    integer :: k
    nb = this%record_bytes(centre)
    do k = 1, size(entities)
      off = (k - 1)*nb
      call this%pack_one(centre, entities(k), buf(off + 1:off + nb))
    end do
  end subroutine registry_pack

  !> Unpack records from buf, one after another, into the entities listed (of a centre).
  subroutine registry_unpack(this, centre, buf, entities)
    class(field_registry_t), intent(inout) :: this
    integer, intent(in) :: centre
    integer(int8), intent(in) :: buf(:)
    integer, intent(in) :: entities(:)
    integer(i8) :: nb, off
    integer :: k
    nb = this%record_bytes(centre)
    do k = 1, size(entities)
      off = (k - 1)*nb
      call this%unpack_one(centre, entities(k), buf(off + 1:off + nb))
    end do
  end subroutine registry_unpack

  !> Move the first n fields of from into to (allocated here with n + extra fields, from
  !> deallocated): their storage keeps its address (no copy of the values), a borrowed field
  !> its view.
  subroutine move_fields(from, to, n, extra)
    type(field_t), allocatable, intent(inout) :: from(:)
    type(field_t), allocatable, intent(out) :: to(:)
    integer, intent(in) :: n, extra
    integer :: k
    allocate(to(n + extra))
    do k = 1, n
      call move_alloc(from(k)%name, to(k)%name)
      to(k)%centre = from(k)%centre
      to(k)%kind = from(k)%kind
      to(k)%width = from(k)%width
      if (allocated(from(k)%r)) call move_alloc(from(k)%r, to(k)%r)
      if (allocated(from(k)%i)) call move_alloc(from(k)%i, to(k)%i)
      to(k)%borrowed = from(k)%borrowed
      to(k)%zeros = from(k)%zeros
      to(k)%rb => from(k)%rb
      to(k)%ib => from(k)%ib
    end do
    deallocate(from)
  end subroutine move_fields

  !> Whether a centre has a borrowed field.
  pure logical function lends(this, centre)
    type(field_registry_t), intent(in) :: this
    integer, intent(in) :: centre
    lends = .false.
    if (this%n_fields > 0) lends = any(this%f(1:this%n_fields)%centre == centre .and. &
                                       this%f(1:this%n_fields)%borrowed)
  end function lends

  !> Bytes of one entity's values of a field.
  pure integer function field_bytes(fk) result(nb)
    type(field_t), intent(in) :: fk
    nb = fk%width*merge(bytes_real, bytes_int, fk%kind == kind_real)
  end function field_bytes
end module iem_fields
